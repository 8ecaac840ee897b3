//! Environment maps for measuring the environment light, and a noise
//! comparison of renders (bench/results/2026-12-02-environment-sampling.md).
//!
//! ```sh
//! cargo run --release --example environment_maps -- write DIR
//! cargo run --release --example environment_maps -- compare REF.exr A.exr [B.exr …]
//! ```
//!
//! `write` generates two equirectangular f32 OpenEXR maps in DIR:
//! `sky-8k.exr` (8192 × 4096, a textured sky over a dark ground, with the
//! sun) and `sun-4k.exr` (4096 × 2048, a plain sky with a small bright sun,
//! 0.53° across at 10⁵ times the sky, carrying about two thirds of the
//! map's power). `compare` prints each image's mean RGB and its RMSE
//! against REF (a render with many more samples), over all pixels.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

/// The sun's direction: azimuth 200°, elevation 35°.
const SUN_AZIMUTH_DEG: f64 = 200.0;
const SUN_ELEVATION_DEG: f64 = 35.0;
/// Angular radius of the sun disc (0.53° across).
const SUN_RADIUS_DEG: f64 = 0.265;
/// The sun's radiance, about 10⁵ times the sky's.
const SUN_RADIANCE: [f32; 3] = [1.0e5, 0.95e5, 0.88e5];

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("write") if args.len() == 2 => {
            let dir = PathBuf::from(&args[1]);
            std::fs::create_dir_all(&dir).expect("create the folder");
            write_map(&dir.join("sun-4k.exr"), 4096, 2048, false);
            write_map(&dir.join("sky-8k.exr"), 8192, 4096, true);
        }
        Some("compare") if args.len() >= 3 => {
            let reference = read_rgb(Path::new(&args[1]));
            let mean = |img: &[[f32; 3]]| {
                let mut sum = [0.0f64; 3];
                for p in img {
                    for c in 0..3 {
                        sum[c] += p[c] as f64;
                    }
                }
                sum.map(|s| s / img.len() as f64)
            };
            println!("| image | mean R, G, B | RMSE vs reference |");
            println!("|---|---|---|");
            for path in std::iter::once(&args[1]).chain(&args[2..]) {
                let img = read_rgb(Path::new(path));
                assert_eq!(img.len(), reference.len(), "{path}: another size");
                let squared: f64 = img
                    .iter()
                    .zip(&reference)
                    .map(|(a, b)| {
                        (0..3)
                            .map(|c| (a[c] as f64 - b[c] as f64).powi(2))
                            .sum::<f64>()
                    })
                    .sum();
                let rmse = (squared / (3 * img.len()) as f64).sqrt();
                let m = mean(&img);
                println!(
                    "| {path} | {:.5}, {:.5}, {:.5} | {rmse:.5} |",
                    m[0], m[1], m[2]
                );
            }
        }
        _ => {
            eprintln!("usage: environment_maps write DIR | compare REF.exr A.exr [B.exr …]");
            std::process::exit(2);
        }
    }
}

/// Writes a `width × height` lat-long map (row 0 straight up): a sky from
/// deep blue at the zenith to pale at the horizon (with soft bands of
/// "cloud" when `textured`), a dark ground, and the sun.
fn write_map(path: &Path, width: usize, height: usize, textured: bool) {
    let sun = direction(
        (90.0 - SUN_ELEVATION_DEG).to_radians(),
        SUN_AZIMUTH_DEG.to_radians(),
    );
    let sun_cos = SUN_RADIUS_DEG.to_radians().cos();
    exr::prelude::write_rgb_file(path, width, height, |x, y| {
        let theta = PI * (y as f64 + 0.5) / height as f64;
        let phi = 2.0 * PI * (x as f64 + 0.5) / width as f64;
        let d = direction(theta, phi);
        if d.iter().zip(&sun).map(|(a, b)| a * b).sum::<f64>() >= sun_cos {
            let [r, g, b] = SUN_RADIANCE;
            return (r, g, b);
        }
        let rgb = if d[2] < 0.0 {
            [0.06, 0.05, 0.04]
        } else {
            let t = d[2];
            let cloud = if textured {
                let waves = (phi * 7.0 + (theta * 23.0).sin() * 2.0).sin()
                    * (theta * 31.0 + (phi * 13.0).cos()).sin();
                0.6 * waves.max(0.0).powi(3)
            } else {
                0.0
            };
            [
                0.55 - 0.35 * t + cloud,
                0.70 - 0.30 * t + cloud,
                1.00 - 0.10 * t + cloud,
            ]
        };
        (rgb[0] as f32, rgb[1] as f32, rgb[2] as f32)
    })
    .expect("write the map");
    println!("wrote {}", path.display());
}

/// Unit vector of polar angle `theta` (from +z) and azimuth `phi`.
fn direction(theta: f64, phi: f64) -> [f64; 3] {
    [
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    ]
}

/// The RGB pixels of the first RGB layer of an EXR, row-major.
fn read_rgb(path: &Path) -> Vec<[f32; 3]> {
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |size, _| (size.width(), vec![[0.0f32; 3]; size.area()]),
        |(w, px): &mut (usize, Vec<[f32; 3]>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = [r, g, b];
        },
    )
    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    image.layer_data.channel_data.pixels.1
}
