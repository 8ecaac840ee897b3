//! Scenes as users write them, drawn at random: every kind of light,
//! environment (a map with a small sun among them), ground, outline, back
//! and built-in gem, mixed. Each must render the same bytes on one thread,
//! on two, and as tiles merged, with no sample NaN, infinite or negative.
//! The fixed scenes of the other tests pin each feature; these pin their
//! combinations, which no one wrote down.

mod common;

use common::cli::{lapidary, scratch, stderr};
use common::maps::write_hdr;
use common::rng::TestRng;
use std::path::Path;

/// The built-in gems: six translucent, two opaque.
const GEMS: [&str; 8] = [
    "green-aventurine",
    "raspberry-aventurine",
    "goldstone",
    "blue-goldstone",
    "pink-sunstone",
    "patterned-sunstone",
    "sunstone",
    "lavender-lepidolite",
];

/// Grounds: none, or a library material of each kind (varnish, glossy
/// paint, metallic paint, frosted paint).
const GROUNDS: [Option<&str>; 5] = [
    None,
    Some("teflon"),
    Some("ceramic-glazing"),
    Some("silver-paint"),
    Some("sugar"),
];

fn pick<'a, T>(rng: &mut TestRng, items: &'a [T]) -> &'a T {
    &items[(rng.unit() * items.len() as f64) as usize]
}

/// One stone's shape (any outline and back, sometimes a buffed top, a
/// dome profile other than the ellipse's) and the lift that rests its
/// back on the ground.
fn shape(rng: &mut TestRng) -> (String, f64) {
    let length = rng.range(4.0, 9.0);
    let (outline, width) = match (rng.unit() * 5.0) as u32 {
        0 => ("Round".to_string(), length),
        1 => ("Oval".to_string(), length * rng.range(0.6, 1.0)),
        2 => (
            format!("Cushion(exponent: {:.2})", rng.range(2.5, 6.0)),
            length * rng.range(0.6, 1.0),
        ),
        3 => ("Pear".to_string(), length * rng.range(0.5, 0.9)),
        _ => ("Marquise".to_string(), length * rng.range(0.4, 0.8)),
    };
    let (base, lift) = if rng.unit() < 0.7 {
        ("Flat".to_string(), 0.0)
    } else {
        let depth = rng.range(0.5, 2.0);
        (format!("Domed(height: {depth:.2})"), depth + 0.01)
    };
    let buff_top = if rng.unit() < 0.25 {
        format!("Some({:.2})", rng.range(0.3, 0.8))
    } else {
        "None".to_string()
    };
    let girdle = rng.range(0.0, 1.0);
    let text = format!(
        "Cabochon(outline: {outline}, length: {length:.2}, width: {width:.2}, \
         dome_height: {:.2}, profile_exponent: {:.2}, girdle_height: {girdle:.2}, \
         base: {base}, buff_top: {buff_top})",
        rng.range(1.5, 5.0),
        rng.range(1.6, 4.0),
    );
    (text, lift + girdle)
}

fn light(rng: &mut TestRng) -> String {
    let (x, y, z) = (
        rng.range(-40.0, 40.0),
        rng.range(-40.0, 40.0),
        rng.range(8.0, 50.0),
    );
    match (rng.unit() * 4.0) as u32 {
        0 => format!(
            "Sphere(centre: ({x:.1}, {y:.1}, {z:.1}), radius: {:.2}, radiance: (200, 180, 160))",
            rng.range(0.3, 3.0)
        ),
        1 => format!("Point(position: ({x:.1}, {y:.1}, {z:.1}), intensity: (900, 900, 900))"),
        2 => format!(
            "Rect(centre: ({x:.1}, {y:.1}, {z:.1}), aim_at: (0, 0, 0), width: {:.1}, \
             height: {:.1}, radiance: (12, 12, 12))",
            rng.range(3.0, 30.0),
            rng.range(3.0, 30.0)
        ),
        _ => format!(
            "Sun(elevation_deg: {:.1}, azimuth_deg: {:.1}, irradiance: (3, 2.9, 2.7))",
            rng.range(5.0, 85.0),
            rng.range(0.0, 360.0)
        ),
    }
}

/// A scene of one to three stones set apart on a line through the middle, a ground or none,
/// zero to four lights (more than a vertex samples), and an environment.
fn scene(seed: u64, maps: &Path) -> String {
    let mut rng = TestRng(0x9E37_79B9_7F4A_7C15 ^ seed.wrapping_mul(0x2545_F491_4F6C_DD1D));
    let count = 1 + (rng.unit() * 3.0) as usize;
    let stones: Vec<String> = (0..count)
        .map(|k| {
            let gem = pick(&mut rng, &GEMS);
            let (shape, lift) = shape(&mut rng);
            format!(
                "Stone(recipe: Some(\"{gem}\"), shape: {shape}, position: ({:.1}, {:.1}, {lift:.2}), \
                 rotation_deg: (0.0, 0.0, {:.1}), seed: Some({k}))",
                12.0 * (k as f64 - (count - 1) as f64 / 2.0),
                rng.range(-2.0, 2.0),
                rng.range(0.0, 180.0),
            )
        })
        .collect();
    let ground = match pick(&mut rng, &GROUNDS) {
        None => "None".to_string(),
        Some(material) => format!("Some(Ground(height: 0.0, material: \"{material}\"))"),
    };
    let lights: Vec<String> = (0..(rng.unit() * 5.0) as usize)
        .map(|_| light(&mut rng))
        .collect();
    let environment = match (rng.unit() * 4.0) as u32 {
        0 => "Constant(radiance: (0.4, 0.45, 0.5))".to_string(),
        1 => format!("Studio(rotation_deg: {:.1})", rng.range(0.0, 360.0)),
        2 => format!("File(path: \"{}\")", maps.join("sky.hdr").display()),
        _ => format!(
            "File(path: \"{}\", rotation_deg: {:.1})",
            maps.join("sun.hdr").display(),
            rng.range(0.0, 360.0)
        ),
    };
    format!(
        "Scene(camera: Orbit(target: (0, 0, 1.5), distance: {:.1}, elevation_deg: {:.1}, \
         azimuth_deg: {:.1}, vertical_fov_deg: {:.1}), stones: [{}], ground: {ground}, \
         lights: [{}], environment: {environment})",
        rng.range(40.0, 90.0),
        rng.range(10.0, 70.0),
        rng.range(-180.0, 180.0),
        rng.range(20.0, 40.0),
        stones.join(", "),
        lights.join(", "),
    )
}

/// A smooth sky, and a dim sky with a 2 × 2-texel sun holding most of the
/// map's power (sampled apart from its sky).
fn write_maps(dir: &Path) {
    write_hdr(&dir.join("sky.hdr"), 64, 32, |col, row| {
        let up = 1.0 - row as f32 / 32.0;
        [
            0.2 + 0.6 * up,
            0.25 + 0.5 * up,
            0.3 + 0.6 * up + 0.01 * col as f32,
        ]
    });
    write_hdr(&dir.join("sun.hdr"), 128, 64, |col, row| {
        if (40..42).contains(&col) && (20..22).contains(&row) {
            [3.0e4, 2.8e4, 2.5e4]
        } else {
            [0.03, 0.04, 0.06]
        }
    });
}

/// Runs `lapidary ARGS…`, asserting success and that no sample was left
/// out as NaN, infinite or negative.
fn render(args: &[&str], what: &str) {
    let out = lapidary(args);
    let report = stderr(&out);
    assert!(out.status.success(), "{what}: {report}");
    assert!(!report.contains("left out"), "{what}: {report}");
}

#[test]
fn random_scenes_render_the_same_bytes_on_any_threads_and_tiles_with_every_sample_finite() {
    let dir = scratch("random-scenes", "bytes");
    write_maps(&dir);
    let s = |p: &Path| p.to_str().unwrap().to_string();
    for seed in 1..=8u64 {
        let text = scene(seed, &dir);
        let path = dir.join(format!("scene-{seed}.ron"));
        std::fs::write(&path, &text).unwrap();
        let what = format!("scene {seed}: {text}");
        let out = |name: &str| dir.join(format!("{seed}-{name}.exr"));
        let common = |threads: &str| {
            [
                "render",
                "--scene",
                &s(&path),
                "--width",
                "20",
                "--height",
                "16",
                "--spp",
                "2",
                "--threads",
                threads,
            ]
            .map(String::from)
            .to_vec()
        };
        for (name, threads) in [("one", "1"), ("two", "2")] {
            let mut args = common(threads);
            args.extend(["-o".into(), s(&out(name))]);
            render(&args.iter().map(String::as_str).collect::<Vec<_>>(), &what);
        }
        let mut tiles = Vec::new();
        for tile in ["0/2", "1/2"] {
            let file = out(&format!("tile{}", &tile[..1]));
            let mut args = common("2");
            args.extend([
                "--tile".into(),
                tile.into(),
                "-q".into(),
                "-o".into(),
                s(&file),
            ]);
            render(&args.iter().map(String::as_str).collect::<Vec<_>>(), &what);
            tiles.push(s(&file));
        }
        let merged = s(&out("merged"));
        let mut args = vec!["merge", "-q", "-o", &merged];
        args.extend(tiles.iter().map(String::as_str));
        render(&args, &what);
        let bytes = |name: &str| std::fs::read(out(name)).unwrap();
        assert!(
            bytes("one") == bytes("two"),
            "{what}: 1 and 2 threads differ"
        );
        assert!(
            bytes("one") == bytes("merged"),
            "{what}: the merged tiles differ"
        );
    }
}
