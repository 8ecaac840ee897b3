//! The command line as a user meets it: `brdf`, `classify`, `list`, and
//! bad material files (exit 1, `file:line:col`, the field and its range,
//! never a panic, never an output file).

mod common;

use std::path::PathBuf;
use std::process::{Command, Output};

fn lapidary(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lapidary"))
        .args(args)
        .output()
        .expect("binary runs")
}

/// The standard output of a command that must succeed (its stderr in the
/// failure message otherwise).
fn stdout_of_success(args: &[&str]) -> String {
    let out = lapidary(args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn scratch_dir(name: &str) -> common::cli::Scratch {
    common::cli::scratch("cli", name)
}

#[test]
fn albedo_prints_csv_for_0_to_85_degrees() {
    let text = stdout_of_success(&["brdf", "gold", "--albedo"]);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "theta_deg,r,g,b");
    assert_eq!(lines.len(), 19);
    let first: Vec<f64> = lines[1].split(',').map(|v| v.parse().unwrap()).collect();
    assert_eq!(first[0], 0.0);
    // Table 4.2's n, k give gold F(0) ≈ 0.97 in red and ≈ 0.39 in blue.
    assert!(first[1] > first[3] + 0.2, "{:?}", first);
}

#[test]
fn eval_prints_three_values_and_matches_lambert_for_a_bare_diffuse_file() {
    let dir = scratch_dir("eval");
    let file = dir.join("matte.ron");
    std::fs::write(&file, "Material(base: Diffuse(colour: (0.5, 0.25, 1.0)))").unwrap();
    let out = lapidary(&["brdf", file.to_str().unwrap(), "--eval", "30,0,45,90"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Vec<f64> = String::from_utf8(out.stdout)
        .unwrap()
        .trim()
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    let pi = std::f64::consts::PI;
    for (got, albedo) in v.iter().zip([0.5, 0.25, 1.0]) {
        assert!((got - albedo / pi).abs() < 1e-5, "{v:?}");
    }
}

#[test]
fn plot_writes_a_png() {
    let dir = scratch_dir("plot");
    let png = dir.join("gold.png");
    let out = lapidary(&["brdf", "gold", "-o", png.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
}

#[test]
fn a_plot_under_another_extension_and_flags_that_do_not_go_together_are_refused() {
    let dir = scratch_dir("plot-refused");
    // The plot is a PNG: a name that says otherwise is refused, nothing written.
    for name in ["gold.jpg", "gold.exr", "gold"] {
        let path = dir.join(name);
        let out = lapidary(&["brdf", "gold", "-o", path.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {stderr}");
        assert!(stderr.contains("must end in .png"), "{name}: {stderr}");
        assert!(!path.exists(), "{name} was written");
    }
    // Usage errors (exit 2): nothing to show, or a reference --eval has not.
    for args in [
        &["brdf", "gold"][..],
        &["brdf", "gold", "--eval", "30,0,30,180", "--reference"],
    ] {
        let out = lapidary(args);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

#[test]
fn classify_names_the_groups_of_section_3_4() {
    for (material, expected) in [
        ("blue-acrylic", "glossy paint"),
        ("sugar", "frosted paint"),
        ("brass", "metallic foil, tinted"),
        ("blue-metallic-car-paint", "metallic paint, tinted"),
        ("blue-metallic-paint", "frosted metal, tinted"),
        ("silver-paint", "patina"),
        ("light-blue-house-paint", "frosted paint, multi-layer"),
    ] {
        let out = lapidary(&["classify", material]);
        assert!(out.status.success());
        let text = String::from_utf8(out.stdout).unwrap();
        assert!(
            text.starts_with(&format!("{material}: {expected}\n")),
            "{material}: {text}"
        );
    }
}

#[test]
fn classify_tells_a_bare_black_base_from_a_varnish() {
    // A black base alone reflects nothing: not a varnish; a layer over it
    // is one. A Conductor with `metal` and `n`/`k` both is refused as such.
    let dir = common::cli::scratch("brdf", "classify-black");
    for (text, expected) in [
        ("Material(layers: [], base: Black)", "black"),
        (
            "Material(layers: [Layer(ior: 1.5)], base: Black)",
            "varnish",
        ),
    ] {
        let path = dir.join("m.ron");
        std::fs::write(&path, text).unwrap();
        let out = lapidary(&["classify", path.to_str().unwrap()]);
        let stdout = String::from_utf8(out.stdout).unwrap();
        assert!(
            out.status.success() && stdout.starts_with(&format!("m: {expected}\n")),
            "{text}: {stdout}"
        );
    }
    let path = dir.join("both.ron");
    std::fs::write(
        &path,
        r#"Material(layers: [], base: Conductor(metal: "gold", n: (0.2, 0.4, 1.4), k: (3.0, 2.3, 1.8)))"#,
    )
    .unwrap();
    let out = lapidary(&["classify", path.to_str().unwrap()]);
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("not both ways; found `metal` together with `n` or `k`"),
        "{stderr}"
    );
}

#[test]
fn list_shows_every_library_material_with_its_class() {
    let out = lapidary(&["list"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    for name in lapidary::recipe::library::builtin_material_names() {
        assert!(text.contains(name), "{name} missing");
    }
    assert!(text.contains("patina") && text.contains("metallic paint"));
}

#[test]
fn every_file_in_the_materials_folder_is_built_in() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("gem-recipes/materials");
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let stem = path.file_stem().unwrap().to_str().unwrap().to_string();
        assert!(
            lapidary::recipe::library::builtin_material_source(&stem).is_some(),
            "{stem} is not embedded"
        );
    }
}

/// Each broken material: the RON text, then fragments the message must contain.
const BROKEN: &[(&str, &str, &[&str])] = &[
    (
        "unknown-field",
        "Material(\n  layers: [Layer(ior: 1.5, rougness_deg: 3.0)],\n  base: Black,\n)",
        &[":2:", "rougness_deg", "did you mean `roughness_deg`"],
    ),
    (
        "wrong-type",
        "Material(\n  layers: [Layer(ior: \"high\")],\n  base: Black,\n)",
        &[":2:", "ior"],
    ),
    (
        "ior-below-one",
        "Material(\n  layers: [Layer(ior: 0.8)],\n  base: Black,\n)",
        &[":2:", "ior", "1 <= ior <= 5"],
    ),
    (
        "negative-roughness",
        "Material(\n  layers: [Layer(ior: 1.5, roughness_deg: -2.0)],\n  base: Black,\n)",
        &[":2:", "roughness_deg", "0 <= roughness_deg < 90"],
    ),
    (
        "roughness-90",
        "Material(\n  layers: [Layer(ior: 1.5, roughness_deg: 90.0)],\n  base: Black,\n)",
        &[":2:", "roughness_deg", "< 90"],
    ),
    (
        "negative-thickness",
        "Material(\n  layers: [Layer(ior: 1.5, thickness: -1.0)],\n  base: Black,\n)",
        &[":2:", "thickness", ">= 0"],
    ),
    (
        "nan-colour",
        "Material(\n  base: Diffuse(colour: (NaN, 0.5, 0.5)),\n)",
        &[":2:", "colour", "0 <= colour <= 1"],
    ),
    (
        "infinite-absorption",
        "Material(\n  layers: [Layer(ior: 1.5, absorption: (inf, 0.0, 0.0))],\n  base: Black,\n)",
        &[":2:", "absorption"],
    ),
    (
        "unknown-metal",
        "Material(\n  base: Conductor(metal: \"gould\"),\n)",
        &[":2:", "unknown metal `gould`", "did you mean `gold`"],
    ),
    (
        "two-iors",
        "Material(\n  layers: [Layer(ior: 1.5, reflectivity: 0.3)],\n  base: Black,\n)",
        &[":2:", "exactly one of `ior`, `reflectivity` or `varnish`"],
    ),
    (
        "truncated",
        "Material(\n  layers: [Layer(ior: 1.5",
        &[":2:"],
    ),
];

#[test]
fn broken_material_files_exit_1_with_file_line_column_and_field() {
    let dir = scratch_dir("broken");
    for (name, text, fragments) in BROKEN {
        let file = dir.join(format!("{name}.ron"));
        std::fs::write(&file, text).unwrap();
        let plot = dir.join(format!("{name}.png"));
        let out = lapidary(&["brdf", file.to_str().unwrap(), "-o", plot.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {stderr}");
        assert!(!stderr.contains("panicked"), "{name}: {stderr}");
        assert!(
            stderr.contains(file.to_str().unwrap()),
            "{name} names no file: {stderr}"
        );
        for fragment in *fragments {
            assert!(
                stderr.contains(fragment),
                "{name}: `{fragment}` not in: {stderr}"
            );
        }
        assert!(!plot.exists(), "{name}: an output file was written");
    }
}

#[test]
fn unknown_library_name_suggests_the_closest() {
    let out = lapidary(&["brdf", "sliver", "--albedo"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("did you mean `silver`"));
}

#[test]
fn plot_into_a_missing_directory_fails_before_work_and_writes_nothing() {
    let out = lapidary(&["brdf", "gold", "-o", "/nonexistent-dir/gold.png"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("does not exist"));
}

#[test]
fn bad_eval_angles_are_refused() {
    // Out of range: bad input (exit 1).
    let out = lapidary(&["brdf", "gold", "--eval", "95,0,10,0"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("[0, 90]"));
    // Not four numbers: a usage error (exit 2), as clap's own.
    for (value, says) in [
        ("30,0,30", "expected four angles"),
        ("a,0,30,0", "`a` is not a number"),
    ] {
        let out = lapidary(&["brdf", "gold", "--eval", value]);
        assert_eq!(out.status.code(), Some(2), "{value}");
        assert!(
            String::from_utf8_lossy(&out.stderr).contains(says),
            "{value}"
        );
    }
}

#[test]
fn a_closed_output_pipe_ends_quietly_without_a_panic() {
    use std::io::{BufRead, BufReader};
    let mut child = Command::new(env!("CARGO_BIN_EXE_lapidary"))
        .args(["brdf", "gold", "--albedo"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert_eq!(first, "theta_deg,r,g,b\n");
    // The reader is dropped here: the next line hits a closed pipe.
    let out = child.wait_with_output().unwrap();
    assert!(!String::from_utf8_lossy(&out.stderr).contains("panicked"));
    assert_eq!(out.status.code(), Some(0));
}

#[test]
fn a_directory_or_non_utf8_file_is_refused_with_its_name() {
    let dir = scratch_dir("notfile");
    let folder = dir.join("folder.ron");
    std::fs::create_dir_all(&folder).unwrap();
    let binary = dir.join("binary.ron");
    std::fs::write(&binary, [0x4d, 0x61, 0xff, 0xfe, 0x00]).unwrap();
    for (path, fragment) in [(&folder, "is a directory"), (&binary, "not UTF-8")] {
        let out = lapidary(&["brdf", path.to_str().unwrap(), "--albedo"]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains(path.to_str().unwrap()) && stderr.contains(fragment),
            "{stderr}"
        );
    }
}

#[test]
fn slice_prints_the_lobe_in_the_plane_with_the_walk_beside_it() {
    // Gold, a bare metal: its lobe peaks on the mirror side (θₒ = +30° for
    // light at 30°), next to nothing comes back on the light's side near the
    // horizon, and the model agrees with its random walk at the peak.
    let text = stdout_of_success(&["brdf", "gold", "--slice", "30", "--reference"]);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[0],
        "theta_o_deg,r,g,b,reference_r,reference_g,reference_b"
    );
    let rows: Vec<Vec<f64>> = lines[1..]
        .iter()
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 59);
    assert_eq!((rows[0][0], rows[58][0]), (-87.0, 87.0));
    let peak = rows.iter().max_by(|a, b| a[1].total_cmp(&b[1])).unwrap();
    assert!((peak[0] - 30.0).abs() <= 3.0, "peak at {}°", peak[0]);
    assert!(
        (peak[1] / peak[4] - 1.0).abs() < 0.1,
        "model {} against the walk {} at the peak",
        peak[1],
        peak[4]
    );
    // (The compensation lobe, spread over the hemisphere, may print 1e-6.)
    assert!(
        rows[0][1] < 1e-5,
        "light's side at the horizon: {:?}",
        rows[0]
    );

    // Out of range: a clear message and exit 1.
    let out = lapidary(&["brdf", "gold", "--slice", "95"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--slice 95: allowed 0 to 90"));
}
