//! `lapidary gallery`: the files it writes, what the sheets hold (measured
//! on the PNGs), the physics figure 3.2 shows, its refusals, determinism.
//!
//! Most runs use `--draft` (materials without the compensation tables,
//! several times quicker to compile) and tiny images, so the whole file
//! runs in seconds; one test renders without it and checks the gallery's
//! image is the one `lapidary render` makes.

mod common;

use common::cli::{lapidary, stderr};
use std::path::Path;
use std::process::Output;

use image::RgbImage;
use lapidary::gallery::figures::{FIGURE_3_2_THICKNESSES, FRAME_COLOUR};
use lapidary::recipe::library::builtin_gem_names;

fn scratch(name: &str) -> common::cli::Scratch {
    common::cli::scratch("gallery", name)
}

fn gallery(dir: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["gallery", "-o", dir.to_str().unwrap()];
    args.extend_from_slice(extra);
    lapidary(&args)
}

fn load(path: &Path) -> RgbImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8()
}

/// The tiles of a sheet, found by their one-pixel frames: (left, top,
/// right, bottom) of each frame, in reading order. A frame's top and
/// bottom edges are horizontal runs of exactly [`FRAME_COLOUR`] at least
/// `min_side` long; labels never use that colour, and a dithered render
/// cannot hold such a run of one exact colour. Each top edge is paired
/// with the next run below it spanning the same columns.
fn frames(img: &RgbImage, min_side: u32) -> Vec<(u32, u32, u32, u32)> {
    let mut runs = Vec::new();
    for y in 0..img.height() {
        let mut x = 0;
        while x < img.width() {
            if *img.get_pixel(x, y) == FRAME_COLOUR {
                let start = x;
                while x < img.width() && *img.get_pixel(x, y) == FRAME_COLOUR {
                    x += 1;
                }
                if x - start >= min_side {
                    runs.push((start, x - 1, y));
                }
            } else {
                x += 1;
            }
        }
    }
    let mut used = vec![false; runs.len()];
    let mut out = Vec::new();
    for i in 0..runs.len() {
        if used[i] {
            continue;
        }
        let (l, r, top) = runs[i];
        let bottom = (i + 1..runs.len()).find(|&j| !used[j] && runs[j].0 == l && runs[j].1 == r);
        let j = bottom.unwrap_or_else(|| panic!("frame at ({l}, {top}) has no bottom edge"));
        used[i] = true;
        used[j] = true;
        out.push((l, top, r, runs[j].2));
    }
    out
}

/// Mean RGB in [0, 1] over the (2k+1)² pixels around (cx, cy).
fn mean_rgb(img: &RgbImage, cx: u32, cy: u32, k: u32) -> [f64; 3] {
    let mut sum = [0.0; 3];
    let mut n = 0.0;
    for y in cy - k..=cy + k {
        for x in cx - k..=cx + k {
            let p = img.get_pixel(x, y);
            for c in 0..3 {
                sum[c] += f64::from(p[c]) / 255.0;
            }
            n += 1.0;
        }
    }
    sum.map(|s| s / n)
}

/// HSV (hue in degrees, saturation, value) of an RGB colour.
fn hsv([r, g, b]: [f64; 3]) -> (f64, f64, f64) {
    let max = r.max(g).max(b);
    let min = r.min(g).min(b);
    let chroma = max - min;
    let hue = if chroma == 0.0 {
        0.0
    } else if max == r {
        60.0 * ((g - b) / chroma).rem_euclid(6.0)
    } else if max == g {
        60.0 * ((b - r) / chroma + 2.0)
    } else {
        60.0 * ((r - g) / chroma + 4.0)
    };
    let saturation = if max > 0.0 { chroma / max } else { 0.0 };
    (hue, saturation, max)
}

#[test]
fn writes_every_gem_the_contact_sheet_the_figures_and_the_turntable() {
    let dir = scratch("all");
    let out = gallery(&dir, &["--size", "32", "--spp", "2", "--draft"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let gems: Vec<&str> = builtin_gem_names().collect();
    let figures = [
        "gallery",
        "figure-4-11",
        "figure-3-2",
        "figure-4-3",
        "figure-4-5b",
        "turntable-goldstone",
    ];
    for name in gems.iter().chain(figures.iter()) {
        let path = dir.join(format!("{name}.png"));
        let bytes = std::fs::metadata(&path)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            .len();
        assert!(bytes < 1_000_000, "{name}.png is {bytes} bytes");
        load(&path);
    }
    // Nothing else: no temporary files left behind.
    let count = std::fs::read_dir(&dir).unwrap().count();
    assert_eq!(count, gems.len() + figures.len());
    // One progress line per image written.
    let wrote = stderr(&out)
        .lines()
        .filter(|l| l.starts_with("wrote "))
        .count();
    assert_eq!(wrote, gems.len() + figures.len(), "{}", stderr(&out));
    // A gem image has the size asked for.
    let first = load(&dir.join(format!("{}.png", gems[0])));
    assert_eq!(first.dimensions(), (32, 32));
    // The contact sheet holds one framed 32-px thumbnail per gem (a frame
    // adds a pixel on each side: 34 px).
    let sheet = frames(&load(&dir.join("gallery.png")), 30);
    assert_eq!(sheet.len(), gems.len(), "{sheet:?}");
    assert!(sheet
        .iter()
        .all(|&(l, t, r, b)| r - l + 1 == 34 && b - t + 1 == 34));
    // Figure 4.11 shows the 24 library materials, figure 3.2 the twelve
    // thicknesses of its caption, figure 4.3 two materials.
    assert_eq!(frames(&load(&dir.join("figure-4-11.png")), 30).len(), 24);
    assert_eq!(frames(&load(&dir.join("figure-3-2.png")), 30).len(), 12);
    assert_eq!(frames(&load(&dir.join("figure-4-3.png")), 30).len(), 2);
}

#[test]
fn figure_3_2_grows_more_saturated_then_darker_and_redder_with_thickness() {
    let dir = scratch("fig32");
    // 192-px gems give 48-px spheres (a quarter of the size).
    let out = gallery(
        &dir,
        &[
            "--only",
            "figure-3-2",
            "--size",
            "192",
            "--spp",
            "16",
            "--draft",
            "-q",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(stderr(&out), "", "-q prints nothing");
    // Only the figure was asked for.
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
    let img = load(&dir.join("figure-3-2.png"));
    let tiles = frames(&img, 40);
    assert_eq!(tiles.len(), FIGURE_3_2_THICKNESSES.len());
    // The camera aims at the sphere's centre, so the frame's centre is the
    // sphere's; there the view is along the normal and the key light's
    // highlight is off to the upper left.
    let colour: Vec<(f64, f64, f64)> = tiles
        .iter()
        .map(|&(l, t, r, b)| hsv(mean_rgb(&img, (l + r) / 2, (t + b) / 2, 3)))
        .collect();
    let at = |d: f64| {
        let i = FIGURE_3_2_THICKNESSES.iter().position(|&x| x == d).unwrap();
        colour[i]
    };
    // Beer–Lambert (eq. 3.5): each channel keeps exp(−α d (1/cosθv' +
    // 1/cosθl')) of the white base's light. The yellow varnish absorbs blue
    // most (α = 0.9 against 0.1 green, 0.05 red per unit): with no layer
    // the sphere is white (saturation near 0), at d = 0.4 blue keeps about
    // exp(−0.72) ≈ 0.5 of what red keeps, so the colour is a clearly
    // saturated yellow, and at 1.6 blue is almost gone.
    let (_, s0, _) = at(0.0);
    let (_, s04, _) = at(0.4);
    let (h16, s16, v16) = at(1.6);
    assert!(s0 < 0.15, "d = 0 should be near white: saturation {s0}");
    assert!(s04 > s0 + 0.1, "saturation 0.4: {s04}, 0: {s0}");
    assert!(s16 > s04, "saturation 1.6: {s16}, 0.4: {s04}");
    // Thicker still, red and green fall too: at d = 15 red keeps about
    // exp(−1.5) ≈ 0.2 of its light against exp(−0.16) ≈ 0.85 at 1.6, so the
    // value (the brightest channel, red) drops; green (α twice red's) falls
    // faster than red, so the hue turns from yellow towards red.
    let (h15, _, v15) = at(15.0);
    assert!(v15 < 0.8 * v16, "value 15: {v15}, 1.6: {v16}");
    assert!(h15 < h16 - 10.0, "hue 15: {h15}°, 1.6: {h16}°");
    assert!(
        (40.0..70.0).contains(&h16),
        "d = 1.6 should be yellow: {h16}°"
    );
}

#[test]
fn an_unknown_only_name_exits_1_naming_it_with_a_suggestion() {
    let parent = scratch("unknown");
    let dir = parent.join("out");
    let out = gallery(&dir, &["--only", "figure-3-2", "green-aventurin"]);
    assert_eq!(out.status.code(), Some(1));
    let err = stderr(&out);
    assert!(err.contains("--only green-aventurin"), "{err}");
    assert!(err.contains("did you mean `green-aventurine`"), "{err}");
    // Refused before anything was made: not even the folder.
    assert!(!dir.exists());
}

#[test]
fn size_zero_and_a_file_as_the_folder_are_refused() {
    let dir = scratch("refuse");
    let out = gallery(&dir, &["--size", "0"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("--size 0: allowed 1 to"),
        "{}",
        stderr(&out)
    );
    let file = dir.join("not-a-folder");
    std::fs::write(&file, "x").unwrap();
    let out = gallery(&file, &["--only", "figure-4-3", "--draft"]);
    assert_eq!(out.status.code(), Some(1));
    let err = stderr(&out);
    assert!(
        err.contains("not-a-folder") && err.contains("not a directory"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
    // A missing folder (two levels deep) is created.
    let nested = dir.join("a").join("b");
    let out = gallery(
        &nested,
        &[
            "--only",
            "figure-4-3",
            "--size",
            "32",
            "--spp",
            "1",
            "--draft",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(nested.join("figure-4-3.png").is_file());
}

#[test]
fn a_gem_is_the_same_bytes_on_one_thread_and_as_lapidary_render_makes_it() {
    // Every pixel is a pure function of (scene, gem, seed, pixel, sample):
    // one worker thread or two, gallery or `lapidary render` with the same
    // size, spp and seed 0, the bytes must be the same.
    let dir = scratch("same");
    let out = gallery(
        &dir,
        &[
            "--only",
            "green-aventurine",
            "--size",
            "24",
            "--spp",
            "2",
            "--threads",
            "1",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let rendered = dir.join("render.png");
    let out = lapidary(&[
        "render",
        "green-aventurine",
        "-o",
        rendered.to_str().unwrap(),
        "--size",
        "24",
        "--spp",
        "2",
        "--threads",
        "2",
        "-q",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let a = std::fs::read(dir.join("green-aventurine.png")).unwrap();
    let b = std::fs::read(&rendered).unwrap();
    assert!(a == b, "gallery and render differ");
}

#[test]
fn a_figure_is_the_same_bytes_on_one_thread_and_on_two() {
    let one = scratch("threads-1");
    let two = scratch("threads-2");
    for (dir, threads) in [(&one, "1"), (&two, "2")] {
        let out = gallery(
            dir,
            &[
                "--only",
                "figure-4-3",
                "--size",
                "32",
                "--spp",
                "2",
                "--draft",
                "--threads",
                threads,
            ],
        );
        assert!(out.status.success(), "{}", stderr(&out));
    }
    let a = std::fs::read(one.join("figure-4-3.png")).unwrap();
    let b = std::fs::read(two.join("figure-4-3.png")).unwrap();
    assert!(a == b, "figure 4.3 depends on the thread count");
}
