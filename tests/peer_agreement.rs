//! lapidary against another renderer: the peer scene of `bench/` (issue 6)
//! rendered small here must show the ground and stone brightness that
//! Mitsuba 3.9.1 (`llvm_ad_rgb`, `plastic` with `nonlinear: true`, a
//! diffuse ground, the same sphere light and sky) measured at 512², 64 spp
//! in `bench/compare` (bench/README.md). Mitsuba's numbers are an
//! independent reference: a different integrator and a different BSDF
//! implementation (its coated-diffuse closed form against our single
//! crossing plus compensation), so agreement checks the light units, the
//! camera, the geometry and the layered BRDF's energy together.

use lapidary::brdf::Rgb;
use lapidary::render::film::{render, Film, FilmSettings};
use lapidary::render::prepare::{camera_for, prepare_scene};
use lapidary::scene::load_scene;
use std::path::Path;

/// Mean linear RGB over the patch (x0, y0, x1, y1), in fractions of the
/// image, as `bench/compare` measures it.
fn patch_mean(rgb: &[[f32; 3]], side: u32, patch: [f64; 4]) -> Rgb {
    let [x0, y0, x1, y1] = patch.map(|f| (f * f64::from(side)).round() as usize);
    let mut sum = Rgb::ZERO;
    for y in y0..y1 {
        for x in x0..x1 {
            let p = rgb[y * side as usize + x];
            sum += Rgb::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
        }
    }
    sum / ((x1 - x0) * (y1 - y0)) as f64
}

/// `bench/<file>` rendered at `side`², `spp` samples a pixel, with at most
/// `bounces` bounces and the film seed `seed`.
fn render_bench_scene(file: &str, side: u32, spp: u32, bounces: u32, seed: u64) -> Film {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("bench")
        .join(file);
    let scene = load_scene(&path).unwrap();
    let cache = lapidary::recipe::TableCache::in_memory();
    let tables = lapidary::recipe::Tables::Computed(&cache);
    let prepared = prepare_scene(
        &scene,
        &lapidary::recipe::gem::GemSource::load("green-aventurine").unwrap(),
        None,
        bounces,
        tables,
        &|_| {},
    )
    .unwrap();
    let camera = camera_for(&scene, side, side);
    render(
        &prepared,
        &camera,
        &FilmSettings::new(side, side, spp, seed),
        &|_| {},
    )
}

#[test]
fn the_peer_scene_matches_mitsubas_ground_and_stone() {
    let side = 128;
    let film = render_bench_scene("peer-scene.ron", side, 64, 4, 3);
    // bench/compare's patches and Mitsuba's means (bench/README.md).
    let checks = [
        (
            "ground",
            [0.08, 0.78, 0.23, 0.94],
            Rgb::new(0.548062, 0.549472, 0.548342),
        ),
        (
            "stone",
            [0.35, 0.45, 0.45, 0.55],
            Rgb::new(0.059026, 0.348338, 0.116647),
        ),
    ];
    for (name, patch, mitsuba) in checks {
        let ours = patch_mean(&film.rgb, side, patch);
        // At 512² bench/compare finds 0.05 % (ground) and ≤ 1.2 % (stone);
        // here, at 128² with the patch's coarser pixels and its sampling
        // noise, 0.3 % and ≤ 1.9 %: 3 % leaves room for noise, not for a
        // wrong light unit (π, 4π) or a lost or doubled coat reflection.
        let relative = (ours - mitsuba).abs() / mitsuba;
        assert!(
            relative.max_element() < 0.03,
            "{name}: lapidary {ours} vs Mitsuba {mitsuba} (relative {relative})"
        );
    }
}

/// The middle of the stone of `bench/peer-scene-*-alone.ron` at 64²:
/// pixels 20..44 × 26..38, as fractions of the image.
const MIDDLE_OF_THE_ALONE_STONE: [f64; 4] = [20.0 / 64.0, 26.0 / 64.0, 44.0 / 64.0, 38.0 / 64.0];

/// A translucent stone alone (no ground) must show Mitsuba 3's colour in
/// the middle of the stone within 2 % in every channel (issue 26's test 5):
/// `scene` at 64², `spp` samples a pixel, 64 bounces (Mitsuba: `max_depth`
/// 256; both effectively unlimited), against `mitsuba`, the mean of
/// Mitsuba's renders at 64² and 128², 32768 spp (bench/results/
/// 2026-12-03-translucent-stones-vs-mitsuba.md).
fn assert_the_stone_matches_mitsuba(scene: &str, spp: u32, mitsuba: Rgb) {
    let side = 64;
    let film = render_bench_scene(scene, side, spp, 64, 1);
    let ours = patch_mean(&film.rgb, side, MIDDLE_OF_THE_ALONE_STONE);
    let relative = (ours - mitsuba).abs() / mitsuba;
    assert!(
        relative.max_element() < 0.02,
        "{scene}: lapidary {ours} vs Mitsuba {mitsuba} (relative {relative})"
    );
}

/// A clear absorbing body (IOR 1.5, σa = (0.3, 0.1, 0.6) per unit): the
/// smooth dielectric's reflection and refraction, total internal
/// reflection and Beer–Lambert together, against Mitsuba's `dielectric`
/// around a `homogeneous` medium of albedo 0 (`volpath`).
#[test]
fn a_clear_absorbing_stone_matches_mitsubas_colour() {
    assert_the_stone_matches_mitsuba(
        "peer-scene-clear-alone.ron",
        // Within 0.4 % at 1024 spp (any seed; the bench's 0.3 %).
        1024,
        Rgb::new(0.211472, 0.247772, 0.171470),
    );
}

/// The same body scattering (σs = 0.5 per unit, Henyey–Greenstein g = 0.5):
/// free flights, the phase function and the connections through the
/// surface, against the same `volpath` with an `hg` phase.
#[test]
fn a_scattering_stone_matches_mitsubas_colour() {
    assert_the_stone_matches_mitsuba(
        "peer-scene-scattering-alone.ron",
        // Light that reflects inside before it leaves is heavy-tailed:
        // seeds 1–4 at 4096 spp came within 0.9 % (at 1024 spp, 1.9 %).
        4096,
        Rgb::new(0.257159, 0.308280, 0.204267),
    );
}
