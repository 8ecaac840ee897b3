//! `lapidary maps`: the figure 4.6 sheet of a gem, and its bad input.

mod common;

use std::process::{Command, Output};

fn lapidary(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lapidary"))
        .args(args)
        .output()
        .expect("binary runs")
}

fn scratch(name: &str) -> common::cli::Scratch {
    common::cli::scratch("maps", name)
}

#[test]
fn maps_sheet_has_four_panels_and_a_sparse_glitter_panel() {
    let dir = scratch("sheet");
    let png = dir.join("lepidolite.png");
    let out = lapidary(&[
        "maps",
        "lavender-lepidolite",
        "-o",
        png.to_str().unwrap(),
        "--size",
        "96",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(&png).unwrap().to_rgb8();
    // Four 96-px panels with 12-px margins.
    assert_eq!(img.width(), 12 + 4 * (96 + 12));
    // Panel ② (glitter map): the recipe fills 2 % of its glitter cells, so
    // most of the panel is dark and a little of it bright.
    let bottom = img.height() - 12;
    let x0 = 12 + 96 + 12;
    let (mut bright, mut total) = (0u32, 0u32);
    for y in bottom - 96..bottom {
        for x in x0..x0 + 96 {
            total += 1;
            if img.get_pixel(x, y).0[0] > 100 {
                bright += 1;
            }
        }
    }
    let fraction = bright as f64 / total as f64;
    assert!(
        fraction > 0.001 && fraction < 0.2,
        "bright fraction {fraction}"
    );
}

#[test]
fn every_gem_file_is_built_in() {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("gem-recipes");
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "ron") {
            let stem = path.file_stem().unwrap().to_str().unwrap().to_string();
            assert!(
                lapidary::recipe::library::builtin_gem_source(&stem).is_some(),
                "{stem} is not embedded"
            );
        }
    }
}

#[test]
fn maps_refuses_bad_input_with_exit_1_and_writes_nothing() {
    let dir = scratch("bad");
    let png = dir.join("out.png");
    let exr = dir.join("out.exr");
    let broken = dir.join("broken.ron");
    std::fs::write(
        &broken,
        "Gem(\n  seed: 1,\n  surface: \"nothing\",\n  colour: 3,\n)",
    )
    .unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["maps", "lavender-lepidolit", "-o", png.to_str().unwrap()],
            "did you mean `lavender-lepidolite`",
        ),
        (
            vec![
                "maps",
                "lavender-lepidolite",
                "-o",
                png.to_str().unwrap(),
                "--size",
                "0",
            ],
            "--size 0",
        ),
        (
            vec![
                "maps",
                "lavender-lepidolite",
                "-o",
                png.to_str().unwrap(),
                "--extent",
                "NaN",
            ],
            "--extent",
        ),
        (
            vec![
                "maps",
                "lavender-lepidolite",
                "-o",
                png.to_str().unwrap(),
                "--extent",
                "1e300",
            ],
            "allowed above 0 up to 1000 texture units",
        ),
        (
            vec!["maps", "lavender-lepidolite", "-o", "/no/such/dir/x.png"],
            "does not exist",
        ),
        (
            vec!["maps", "lavender-lepidolite", "-o", exr.to_str().unwrap()],
            "must end in .png",
        ),
        (
            vec![
                "maps",
                broken.to_str().unwrap(),
                "-o",
                png.to_str().unwrap(),
            ],
            "broken.ron:",
        ),
    ];
    for (args, fragment) in cases {
        let out = lapidary(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains(fragment),
            "{args:?}: `{fragment}` not in {stderr}"
        );
        assert!(!stderr.contains("panicked"));
        assert!(!png.exists() && !exr.exists());
    }
}

#[test]
fn ctrl_c_while_the_sheet_is_written_leaves_no_file() {
    let dir = scratch("interrupt");
    let png = dir.join("big.png");
    let child = Command::new(env!("CARGO_BIN_EXE_lapidary"))
        .args(["maps", "lavender-lepidolite", "--size", "2048", "-o"])
        .arg(&png)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Ctrl-C as soon as the temporary file of the PNG appears (the sheet
    // is being encoded), or after 30 s.
    let started = std::time::Instant::now();
    let writing = || {
        std::fs::read_dir(&dir)
            .unwrap()
            .any(|e| e.unwrap().file_name().to_string_lossy().ends_with(".tmp"))
    };
    while !writing() && started.elapsed().as_secs() < 30 {
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    let seen_writing = writing();
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let left: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    match out.status.code() {
        // Stopped midway: no temporary file is left, and the sheet only if
        // its file was renamed into place, whole, before the signal came.
        Some(1) => {
            assert!(stderr.contains("interrupted"), "{stderr}");
            assert!(
                left.is_empty() || (left == ["big.png"] && image::open(&png).is_ok()),
                "left behind: {left:?}"
            );
        }
        // Finished before the signal: the sheet alone.
        Some(0) => assert_eq!(left, ["big.png"], "{stderr}"),
        other => panic!("exit {other:?} (seen writing: {seen_writing}): {stderr}"),
    }
}

#[test]
fn narrow_panels_keep_their_labels_apart() {
    // At 48 px a panel is narrower than "1 surface map": the labels must
    // shorten rather than run into the margin between panels (they did).
    let dir = scratch("narrow");
    let png = dir.join("narrow.png");
    let out = lapidary(&[
        "maps",
        "lavender-lepidolite",
        "-o",
        png.to_str().unwrap(),
        "--size",
        "48",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(&png).unwrap().to_rgb8();
    let (panel, margin) = (48, 12);
    let background = *img.get_pixel(0, img.height() - 1);
    // The rows above the panels: title and labels.
    let panels_top = img.height() - margin - panel;
    for k in 1..4 {
        let gap = k * (panel + margin);
        for x in gap..gap + margin {
            for y in 24..panels_top {
                assert_eq!(*img.get_pixel(x, y), background, "ink at ({x}, {y})");
            }
        }
    }
}
