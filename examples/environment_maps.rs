//! Environment maps for measuring the environment light, and a noise
//! comparison of renders (bench/results/2026-12-02-environment-sampling.md).
//!
//! ```sh
//! cargo run --release --example environment_maps -- write DIR
//! cargo run --release --example environment_maps -- spread A.exr B.exr [C.exr …]
//! ```
//!
//! `write` generates two equirectangular f32 OpenEXR maps in DIR:
//! `sky-8k.exr` (8192 × 4096, a textured sky over a dark ground, with the
//! sun) and `sun-4k.exr` (4096 × 2048, a plain sky with a small bright sun,
//! 0.53° across at 10⁵ times the sky, carrying about two thirds of the
//! map's power). `spread` takes renders of one scene with different
//! `--seed`s and prints the mean of their average and the per-pixel
//! variance across them (the noise of one render), averaged over pixels,
//! without the noisiest 1 % of pixels, and its median.

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
        Some("spread") if args.len() >= 3 => {
            // Renders of one scene with different seeds: the mean of the
            // average image, and the per-pixel variance across renders
            // (n − 1 in the denominator) averaged over pixels and channels.
            let images: Vec<Vec<[f32; 3]>> =
                args[1..].iter().map(|p| read_rgb(Path::new(p))).collect();
            let (n, pixels) = (images.len() as f64, images[0].len());
            let mut mean = [0.0f64; 3];
            // Per pixel, the variance across renders averaged over channels.
            let mut variances: Vec<f64> = (0..pixels)
                .map(|i| {
                    let mut v = 0.0;
                    for (c, mean_c) in mean.iter_mut().enumerate() {
                        let values = images.iter().map(|img| img[i][c] as f64);
                        let m = values.clone().sum::<f64>() / n;
                        *mean_c += m / pixels as f64;
                        v += values.map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0) / 3.0;
                    }
                    v
                })
                .collect();
            variances.sort_by(f64::total_cmp);
            let average = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
            // Fireflies (paths BRDF sampling alone finds) dominate the mean
            // and are the same for any light sampling: also without the
            // noisiest 1 % of pixels, and the median.
            let kept = &variances[..pixels - pixels / 100];
            println!(
                "{} renders: mean {:.5}, {:.5}, {:.5}; pixel variance: mean {:.4e}, \
                 without the top 1 % {:.4e}, median {:.4e}",
                images.len(),
                mean[0],
                mean[1],
                mean[2],
                average(&variances),
                average(kept),
                variances[pixels / 2]
            );
        }
        _ => {
            eprintln!("usage: environment_maps write DIR | spread A.exr B.exr [C.exr …]");
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
