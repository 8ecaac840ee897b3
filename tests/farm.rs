//! Turntables, tiles, `merge` and `batch` through the real binary: any
//! split of any frame on any number of threads merges to the bytes of one
//! render (PNG and EXR); re-run tasks give the same tile or skip a
//! complete one; every tile that does not belong is refused; the
//! HTCondor submit file's own commands run the batch.

mod common;

use common::cli::{lapidary, stderr};
use std::path::{Path, PathBuf};

fn scratch(name: &str) -> common::cli::Scratch {
    common::cli::scratch("farm", name)
}

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Runs lapidary and asserts success.
fn ok(args: &[&str]) -> String {
    let out = lapidary(args);
    assert!(out.status.success(), "lapidary {args:?}: {}", stderr(&out));
    stderr(&out)
}

/// Runs lapidary and asserts the refusal: exit 1, an `error:` naming
/// `expected`, no panic.
fn refused(args: &[&str], expected: &str) -> String {
    let out = lapidary(args);
    let text = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "lapidary {args:?}: {text}");
    assert!(
        text.contains("error:") && !text.contains("panicked"),
        "{text}"
    );
    assert!(
        text.contains(expected),
        "lapidary {args:?}: expected {expected:?} in: {text}"
    );
    text
}

fn bytes(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The settings of every render here: tiny and quick.
const SMALL: [&str; 8] = [
    "render", "sunstone", "--width", "32", "--height", "24", "--spp", "2",
];

#[test]
fn tiles_of_any_frame_on_any_threads_merge_to_the_single_render_bytes() {
    let dir = scratch("bytes");
    let single = |ext: &str, turn: &str| dir.join(format!("single-{turn}.{ext}"));
    for turn in ["stone", "camera"] {
        for ext in ["png", "exr"] {
            let out = single(ext, turn);
            let mut args = SMALL.to_vec();
            args.extend(["--frames", "3", "--turn", turn, "-q", "-o", s(&out)]);
            ok(&args);
        }
    }
    let frame_file = |base: PathBuf, k: u32| {
        let name = base.file_stem().unwrap().to_str().unwrap().to_string();
        let ext = base.extension().unwrap().to_str().unwrap().to_string();
        base.with_file_name(format!("{name}-{k:04}.{ext}"))
    };
    // Frames 0 and 2, both motions, 2 and 3 tiles, 1 or 2 threads per tile.
    for (frame, turn, count) in [
        (0, "stone", 2u32),
        (2, "stone", 3),
        (1, "camera", 2),
        (2, "camera", 3),
    ] {
        let mut tiles = Vec::new();
        for index in 0..count {
            let base = dir.join(format!("t{frame}{turn}{index}of{count}.exr"));
            let (f, tile, threads) = (
                frame.to_string(),
                format!("{index}/{count}"),
                (1 + index % 2).to_string(),
            );
            let mut args = SMALL.to_vec();
            args.extend([
                "--frames", "3", "--frame", &f, "--turn", turn, "--tile", &tile,
            ]);
            args.extend(["--threads", &threads, "-q", "-o", s(&base)]);
            ok(&args);
            tiles.push(frame_file(base, frame));
        }
        tiles.reverse(); // any order
        for ext in ["png", "exr"] {
            let merged = dir.join(format!("merged.{ext}"));
            let mut args = vec!["merge", "-q", "-o", s(&merged)];
            args.extend(tiles.iter().map(|t| s(t)));
            ok(&args);
            assert!(
                bytes(&merged) == bytes(&frame_file(single(ext, turn), frame)),
                "frame {frame} ({turn}) in {count} tiles: the merged {ext} differs from the single render"
            );
        }
    }
    // Turned frames differ; frame 0 is the still.
    assert_ne!(
        bytes(&frame_file(single("png", "stone"), 0)),
        bytes(&frame_file(single("png", "stone"), 1))
    );
    let still = dir.join("still.png");
    let mut args = SMALL.to_vec();
    args.extend(["-q", "-o", s(&still)]);
    ok(&args);
    assert_eq!(bytes(&still), bytes(&frame_file(single("png", "stone"), 0)));
}

#[test]
fn ambient_occlusion_tiles_merge_to_the_occlusion_png() {
    let dir = scratch("ao");
    let single = dir.join("single.png");
    let mut args = SMALL.to_vec();
    args.extend([
        "--ao",
        "3",
        "--exposure",
        "0.5",
        "--seed",
        "7",
        "-q",
        "-o",
        s(&single),
    ]);
    ok(&args);
    let mut tiles = Vec::new();
    for index in 0..2 {
        let tile = dir.join(format!("t{index}.exr"));
        let split = format!("{index}/2");
        let mut args = SMALL.to_vec();
        args.extend([
            "--ao",
            "3",
            "--exposure",
            "0.5",
            "--seed",
            "7",
            "--tile",
            &split,
            "-q",
            "-o",
            s(&tile),
        ]);
        ok(&args);
        tiles.push(tile);
    }
    let merged = dir.join("merged.png");
    ok(&["merge", "-q", "-o", s(&merged), s(&tiles[0]), s(&tiles[1])]);
    assert_eq!(bytes(&merged), bytes(&single));
}

#[test]
fn a_turntable_writes_numbered_frames_an_animated_png_and_a_line_per_frame() {
    let dir = scratch("turntable");
    // A scene that names its turntable (the studio, two frames, camera).
    let studio = lapidary::scene::DEFAULT_SCENE_SOURCE;
    let at = studio.rfind(')').unwrap();
    let scene_text = format!(
        "{}    turntable: Some(Turntable(frames: 2, turn: Camera)),\n)",
        &studio[..at]
    );
    let scene = dir.join("spin.ron");
    std::fs::write(&scene, scene_text).unwrap();
    let out = dir.join("spin.png");
    let mut args = SMALL.to_vec();
    args.extend(["--scene", s(&scene), "-o", s(&out)]);
    let log = ok(&args);
    assert!(
        log.contains("frame 0 of 2") && log.contains("frame 1 of 2 (180.0°)"),
        "{log}"
    );
    // The flags say the same as the scene: the same frames.
    let flagged = dir.join("flagged.png");
    let mut args = SMALL.to_vec();
    args.extend(["--frames", "2", "--turn", "camera", "-q", "-o", s(&flagged)]);
    ok(&args);
    for k in 0..2 {
        let frame = dir.join(format!("spin-{k:04}.png"));
        assert_eq!(
            bytes(&frame),
            bytes(&dir.join(format!("flagged-{k:04}.png")))
        );
    }
    // The animation: two frames, each the frame's own PNG.
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&out).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let control = reader.info().animation_control.expect("an animated PNG");
    assert_eq!(control.num_frames, 2);
    for k in 0..2 {
        let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buffer).unwrap();
        let frame = image::open(dir.join(format!("spin-{k:04}.png")))
            .unwrap()
            .to_rgb8();
        assert_eq!(
            &buffer[..info.buffer_size()],
            frame.as_raw().as_slice(),
            "frame {k}"
        );
    }
    // One frame alone is that frame, and no animation.
    let one = dir.join("one.png");
    let mut args = SMALL.to_vec();
    args.extend(["--scene", s(&scene), "--frame", "1", "-q", "-o", s(&one)]);
    ok(&args);
    assert_eq!(
        bytes(&dir.join("one-0001.png")),
        bytes(&dir.join("spin-0001.png"))
    );
    assert!(!one.exists());
}

#[test]
fn impossible_frames_and_tiles_are_refused_before_any_work() {
    let dir = scratch("flags");
    let exr = dir.join("x.exr");
    let png = dir.join("x.png");
    let cases: [(&[&str], &str, &Path); 9] = [
        (&["--tile", "5/4"], "allowed 0 to 3", &exr),
        (&["--tile", "0/0"], "allowed 1 to 24", &exr),
        (&["--tile", "0/25"], "allowed 1 to 24", &exr),
        (&["--tile", "0/2"], "must end in .exr", &png),
        (&["--frame", "9", "--frames", "4"], "allowed 0 to 3", &png),
        (&["--frames", "0"], "--frames 0: allowed 1 to 3600", &png),
        (&["--frame", "1"], "--frame needs a turntable", &png),
        (&["--turn", "camera"], "--turn needs a turntable", &png),
        // Its film fits in 0.0001 GiB (105 KiB); its animation's 3600
        // frames, kept until the last, do not.
        (
            &["--frames", "3600", "--max-memory", "0.0001"],
            "an animated PNG of 3600 frames of 32 × 24 keeps every frame until the last",
            &png,
        ),
    ];
    for (extra, expected, out) in cases {
        let mut args = SMALL.to_vec();
        args.extend(extra);
        args.extend(["-o", s(out)]);
        refused(&args, expected);
    }
    let usage = lapidary(&["render", "--tile", "a/b", "-o", s(&exr)]);
    assert_eq!(usage.status.code(), Some(2), "{}", stderr(&usage));
    assert!(
        std::fs::read_dir(&dir).unwrap().next().is_none(),
        "a refused render left a file"
    );
}

/// Renders tile `index` of `count` of the small image to `path`, with
/// `spp` samples and `extra` flags.
fn tile(path: &Path, index: u32, count: u32, spp: &str, extra: &[&str]) {
    let split = format!("{index}/{count}");
    let mut args = SMALL.to_vec();
    args[7] = spp;
    args.extend(["--tile", &split, "-q", "-o", s(path)]);
    args.extend(extra);
    ok(&args);
}

#[test]
fn merge_refuses_every_tile_that_does_not_belong_and_writes_nothing() {
    let dir = scratch("refusals");
    let t = |name: &str| dir.join(name);
    tile(&t("a0.exr"), 0, 2, "2", &[]);
    tile(&t("a1.exr"), 1, 2, "2", &[]);
    tile(&t("spp.exr"), 1, 2, "3", &[]);
    tile(&t("seed.exr"), 1, 2, "2", &["--seed", "1"]);
    tile(&t("gem.exr"), 1, 2, "2", &["--bounces", "3"]);
    tile(&t("box.exr"), 1, 2, "2", &["--filter", "box"]);
    tile(&t("of3.exr"), 1, 3, "2", &[]);
    let frame = t("frame.exr"); // written as frame-0001.exr
    let mut args = SMALL.to_vec();
    args.extend([
        "--frames",
        "2",
        "--frame",
        "1",
        "--tile",
        "1/2",
        "-q",
        "-o",
        s(&frame),
    ]);
    ok(&args);
    let mut args = SMALL.to_vec();
    let plain = t("plain.exr");
    args.extend(["-q", "-o", s(&plain)]);
    ok(&args);
    let recipe = t("sunstone.ron");
    std::fs::write(&recipe, lapidary::GemSource::load("sunstone").unwrap().text).unwrap();
    let mut args = SMALL.to_vec();
    let file_gem = t("file-gem.exr");
    args[1] = s(&recipe);
    args.extend(["--tile", "1/2", "-q", "-o", s(&file_gem)]);
    ok(&args);
    // The same gem from a file whose bytes then change.
    let mut args = SMALL.to_vec();
    let file_gem0 = t("file-gem0.exr");
    args[1] = s(&recipe);
    args.extend(["--tile", "0/2", "-q", "-o", s(&file_gem0)]);
    ok(&args);
    std::fs::write(
        &recipe,
        lapidary::GemSource::load("sunstone").unwrap().text + "\n// edited\n",
    )
    .unwrap();
    let mut args = SMALL.to_vec();
    let edited = t("file-gem1-edited.exr");
    args[1] = s(&recipe);
    args.extend(["--tile", "1/2", "-q", "-o", s(&edited)]);
    ok(&args);

    let a0 = bytes(&t("a0.exr"));
    // Damaged copies: cut short, a flipped byte in the pixels, another
    // version in the record (its checksum still right).
    std::fs::write(t("short.exr"), &a0[..a0.len() * 2 / 3]).unwrap();
    let mut flipped = a0.clone();
    let at = flipped.len() - 40;
    flipped[at] ^= 0x5a;
    std::fs::write(t("flipped.exr"), flipped).unwrap();
    let version = format!("version: \"{}\"", env!("CARGO_PKG_VERSION"));
    let other = version.replace('.', ",");
    let at = a0
        .windows(version.len())
        .position(|w| w == version.as_bytes())
        .expect("the record names the version");
    let mut aged = a0.clone();
    aged[at..at + version.len()].copy_from_slice(other.as_bytes());
    std::fs::write(t("version.exr"), aged).unwrap();
    std::fs::write(t("text.exr"), "not an image").unwrap();
    // Two parts: the header checked would be the first, the layer decoded
    // the first valid one.
    {
        use exr::prelude::*;
        let layer = |name: &str| {
            let red = AnyChannel::new("R", FlatSamples::F32(vec![0.5; 64]));
            Layer::new(
                (8, 8),
                LayerAttributes::named(name),
                Encoding::UNCOMPRESSED,
                AnyChannels::sort(SmallVec::from_vec(vec![red])),
            )
        };
        let bounds = IntegerBounds::from_dimensions((8, 8));
        Image::from_layers(ImageAttributes::new(bounds), vec![layer("a"), layer("b")])
            .write()
            .to_file(t("two-parts.exr"))
            .unwrap();
    }

    let out = t("out.png");
    std::fs::write(&out, "existing").unwrap();
    let cases: [(&[&str], &str); 16] = [
        (
            &["a0.exr", "spp.exr"],
            "spp.exr belongs to another render than",
        ),
        (&["a0.exr", "seed.exr"], "its seed is 1, not 0"),
        (&["a0.exr", "gem.exr"], "its bounces is 3, not 8"),
        (&["a0.exr", "box.exr"], "its filter is Box, not Tent"),
        (&["a0.exr", "frame-0001.exr"], "its frame is 1 of 2"),
        (
            &["file-gem0.exr", "file-gem1-edited.exr"],
            "its inputs_sha256 is",
        ),
        (&["a0.exr", "of3.exr"], "different splits"),
        (&["a0.exr"], "tile 1 of 2 is missing"),
        (
            &["a0.exr", "a1.exr", "a1.exr"],
            "tile 1 of 2 is given twice",
        ),
        (&["short.exr", "a1.exr"], "short.exr"),
        (&["flipped.exr", "a1.exr"], "flipped.exr"),
        (&["version.exr", "a1.exr"], "its version is"),
        (&["plain.exr", "a1.exr"], "plain.exr: not a lapidary tile"),
        (&["text.exr", "a1.exr"], "text.exr"),
        (
            &["two-parts.exr", "a1.exr"],
            "two-parts.exr: holds 2 parts, where lapidary writes one",
        ),
        (&["gone.exr", "a1.exr"], "gone.exr: no such tile file"),
    ];
    for (tiles, expected) in cases {
        let paths: Vec<PathBuf> = tiles.iter().map(|n| t(n)).collect();
        let mut args = vec!["merge", "-o", s(&out)];
        args.extend(paths.iter().map(|p| s(p)));
        refused(&args, expected);
        assert_eq!(bytes(&out), b"existing", "{tiles:?} touched the output");
    }
    // An output that is one of the tiles would replace it.
    let tile = bytes(&t("a0.exr"));
    refused(
        &[
            "merge",
            "-o",
            s(&t("a0.exr")),
            s(&t("a0.exr")),
            s(&t("a1.exr")),
        ],
        "the output is one of the tiles",
    );
    assert_eq!(bytes(&t("a0.exr")), tile, "the tile was changed");
    refused(
        &[
            "merge",
            "--threads",
            "0",
            "-o",
            s(&out),
            s(&t("a0.exr")),
            s(&t("a1.exr")),
        ],
        "--threads 0: allowed 1 to 1024",
    );
    ok(&[
        "merge",
        "-q",
        "-o",
        s(&out),
        s(&t("a0.exr")),
        s(&t("a1.exr")),
    ]);
    // The built-in gem and a file of its very text are one input: their
    // tiles merge to the same image.
    let from_file = t("from-file.png");
    ok(&[
        "merge",
        "-q",
        "-o",
        s(&from_file),
        s(&t("a0.exr")),
        s(&t("file-gem.exr")),
    ]);
    assert_eq!(bytes(&from_file), bytes(&out));
}

#[test]
fn a_tile_whose_record_or_header_lies_about_its_size_is_refused_before_its_pixels() {
    use lapidary::farm::record::TILE_NOTE;
    use lapidary::output::exr::{read_exr, write_exr_with_note, Band};
    let dir = scratch("forged");
    let t = |name: &str| dir.join(name);
    tile(&t("a0.exr"), 0, 2, "2", &[]);
    tile(&t("a1.exr"), 1, 2, "2", &[]);
    let a0 = read_exr(&t("a0.exr")).unwrap();
    let record = &a0.notes.iter().find(|(k, _)| k == TILE_NOTE).unwrap().1;
    assert!(record.contains("size: 32x24\n") && record.contains("tile: 0 of 2\n"));
    // The same pixels (rows 0 to 11 of a 32 × 24 image) under a record
    // that says otherwise.
    let forge = |name: &str, size: &str, tile: &str| {
        let text = record
            .replace("size: 32x24\n", &format!("size: {size}\n"))
            .replace("tile: 0 of 2\n", &format!("tile: {tile}\n"));
        let band = Band {
            rows: 0..12,
            image_height_px: 24,
        };
        write_exr_with_note(&t(name), 32, band, a0.channels.clone(), (TILE_NOTE, &text)).unwrap();
    };
    // An image no render makes, split into more tiles than any merge
    // could list: refused at its record (it used to take gigabytes).
    forge("tall.exr", "32x1600000000", "0 of 300000000");
    forge("wide.exr", "4000000000x24", "0 of 2");
    // A record of another size than the file's pixels.
    forge("other.exr", "32x48", "0 of 2");
    let out = t("out.png");
    for (name, expected) in [
        (
            "tall.exr",
            "tall.exr: damaged: its record says the image is 32×1600000000 pixels; allowed: 1 to 32768 a side",
        ),
        ("wide.exr", "allowed: 1 to 32768 a side"),
        (
            "other.exr",
            "other.exr: damaged: it is 32×12 pixels, but tile 0 of 2 of a 32×48 image is 32×24",
        ),
    ] {
        refused(&["merge", "-o", s(&out), s(&t(name)), s(&t("a1.exr"))], expected);
        assert!(!out.exists(), "{name}: an output was written");
    }
    // Of a render split into many tiles, only a few are listed missing.
    let mut args = SMALL.to_vec();
    let many = t("many.exr");
    args.extend(["--tile", "0/24", "-q", "-o", s(&many)]);
    ok(&args);
    refused(
        &["merge", "-o", s(&out), s(&many)],
        "tiles 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, … (23 in all) of 24 are missing",
    );
}

#[test]
fn a_tile_s_exr_sits_at_its_rows_of_the_whole_image() {
    // Other EXR viewers place a tile by its data window within the display
    // window (the whole image); each tile's starts at its first row, and
    // the tiles' rows cover the image once.
    let dir = scratch("data-window");
    let mut next_row = 0;
    for index in 0..3 {
        let path = dir.join(format!("t{index}.exr"));
        tile(&path, index, 3, "1", &[]);
        let meta = exr::meta::MetaData::read_from_file(&path, false).unwrap();
        let header = &meta.headers[0];
        let display = header.shared_attributes.display_window;
        assert_eq!(
            (
                display.position.x(),
                display.position.y(),
                display.size.width(),
                display.size.height()
            ),
            (0, 0, 32, 24),
            "tile {index}'s display window is the whole image"
        );
        let position = header.own_attributes.layer_position;
        assert_eq!((position.x(), position.y()), (0, next_row), "tile {index}");
        assert_eq!(header.layer_size.width(), 32);
        next_row += header.layer_size.height() as i32;
    }
    assert_eq!(next_row, 24, "the tiles' rows cover the image");
}

#[test]
fn tiles_of_one_render_run_from_different_working_folders_merge() {
    // A farm's tasks name the same scene from different folders
    // (`scene.ron` in its folder, `job/scene.ron` above it): the inputs'
    // bytes decide, not the paths as typed. A scene of other bytes is
    // still another render.
    let dir = scratch("working-folders");
    let job = dir.join("job");
    std::fs::create_dir_all(&job).unwrap();
    let scene = lapidary::scene::DEFAULT_SCENE_SOURCE;
    std::fs::write(job.join("scene.ron"), scene).unwrap();
    std::fs::write(job.join("other.ron"), format!("{scene}\n// edited\n")).unwrap();
    let run_in = |cwd: &Path, args: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_lapidary"))
            .args(args)
            .current_dir(cwd)
            .output()
            .expect("binary runs");
        assert!(out.status.success(), "lapidary {args:?}: {}", stderr(&out));
    };
    let tile_in = |cwd: &Path, scene: &str, split: &str, out: &str| {
        let mut args = SMALL.to_vec();
        args.extend(["--scene", scene, "--tile", split, "-q", "-o", out]);
        run_in(cwd, &args);
    };
    tile_in(&job, "scene.ron", "0/2", "t0.exr");
    tile_in(&dir, "job/scene.ron", "1/2", "job/t1.exr");
    tile_in(&dir, "job/other.ron", "1/2", "job/other-t1.exr");
    let mut args = SMALL.to_vec();
    let (scene_path, whole) = (job.join("scene.ron"), job.join("whole.png"));
    args.extend(["--scene", s(&scene_path), "-q", "-o", s(&whole)]);
    ok(&args);
    let merged = job.join("merged.png");
    let (t0, t1) = (job.join("t0.exr"), job.join("t1.exr"));
    ok(&["merge", "-q", "-o", s(&merged), s(&t0), s(&t1)]);
    assert_eq!(bytes(&merged), bytes(&whole));
    // A batch task run again from another folder finds its tile complete
    // (the job names its scene relative to itself: `scene.ron` typed one
    // way, `job/scene.ron` the other).
    std::fs::write(
        job.join("job.ron"),
        r#"Job(output: "out", recipes: ["sunstone"], scenes: ["scene.ron"],
               settings: [Settings(width: 32, height: 24, spp: 2)], tiles: 2)"#,
    )
    .unwrap();
    let batch_in = |cwd: &Path, job_file: &str| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_lapidary"))
            .args(["batch", job_file, "--task", "0"])
            .current_dir(cwd)
            .output()
            .expect("binary runs");
        assert!(out.status.success(), "{}", stderr(&out));
        stderr(&out)
    };
    let first = batch_in(&job, "job.ron");
    assert!(!first.contains("skipped"), "{first}");
    let again = batch_in(&dir, "job/job.ron");
    assert!(again.contains("already complete, skipped"), "{again}");
    refused(
        &[
            "merge",
            "-o",
            s(&merged),
            s(&t0),
            s(&job.join("other-t1.exr")),
        ],
        "its scene is \"job/other.ron\", not \"scene.ron\"",
    );
}

const JOB: &str = r#"Job(
    output: "out",
    recipes: ["sunstone"],
    settings: [Settings(width: 32, height: 24, spp: 2)],
    turntable: Some(Turntable(frames: 2)),
    tiles: 2,
)"#;

#[test]
fn a_batch_task_re_run_gives_the_same_tile_and_a_complete_one_is_skipped() {
    let dir = scratch("resume");
    let job = dir.join("job.ron");
    std::fs::write(&job, JOB).unwrap();
    let list = lapidary(&["batch", s(&job)]);
    assert!(list.status.success(), "{}", stderr(&list));
    let lines = String::from_utf8(list.stdout).unwrap();
    assert_eq!(lines.lines().count(), 4, "{lines}");
    assert!(
        lines.starts_with("0 sunstone-studio-0000.tile0of2\n"),
        "{lines}"
    );
    let tile = dir.join("out/tiles/sunstone-studio-0001.tile1of2.exr");
    ok(&["batch", s(&job), "--task", "3", "-q"]);
    let first = bytes(&tile);
    // A task killed before its rename leaves at most a temporary file; a
    // damaged tile in its place is rendered again, to the same bytes.
    std::fs::write(&tile, &first[..first.len() / 2]).unwrap();
    ok(&["batch", s(&job), "--task", "3", "-q", "--threads", "1"]);
    assert_eq!(bytes(&tile), first);
    let log = ok(&["batch", s(&job), "--task", "3"]);
    assert!(log.contains("already complete, skipped"), "{log}");
    // A complete tile made read-only (kept by its owner) is skipped too.
    let mut permissions = std::fs::metadata(&tile).unwrap().permissions();
    permissions.set_readonly(true);
    std::fs::set_permissions(&tile, permissions.clone()).unwrap();
    let log = ok(&["batch", s(&job), "--task", "3"]);
    assert!(log.contains("already complete, skipped"), "{log}");
    #[allow(clippy::permissions_set_readonly_false)]
    permissions.set_readonly(false);
    std::fs::set_permissions(&tile, permissions).unwrap();
    // A tile of other settings is not this task's output: the merge
    // refuses it, the task renders it again.
    for task in ["0", "1", "2"] {
        ok(&["batch", s(&job), "--task", task, "-q"]);
    }
    ok(&["batch", s(&job), "--merge", "-q"]);
    std::fs::write(&job, JOB.replace("spp: 2", "spp: 3")).unwrap();
    refused(
        &["batch", s(&job), "--merge"],
        "its spp is 2, not 3): run its task again (`lapidary batch",
    );
    refused(&["batch", s(&job), "--merge"], "--task 0`)");
    let log = ok(&["batch", s(&job), "--task", "3"]);
    assert!(!log.contains("skipped"), "{log}");
    assert_ne!(bytes(&tile), first);
}

#[test]
fn a_killed_task_leaves_no_tile_and_its_re_run_gives_the_same_bytes() {
    let dir = scratch("killed");
    let job = dir.join("job.ron");
    // Big enough to be killed while it renders.
    std::fs::write(
        &job,
        JOB.replace(
            "width: 32, height: 24, spp: 2",
            "width: 96, height: 96, spp: 128",
        ),
    )
    .unwrap();
    let tile = dir.join("out/tiles/sunstone-studio-0000.tile0of2.exr");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_lapidary"))
        .args(["batch", s(&job), "--task", "0", "--threads", "1"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Killed once it has compiled its gem and started to trace.
    let mut line = String::new();
    let mut stderr_lines = std::io::BufReader::new(child.stderr.take().unwrap());
    std::io::BufRead::read_line(&mut stderr_lines, &mut line).unwrap();
    assert!(line.contains("compiling gem"), "{line}");
    std::thread::sleep(std::time::Duration::from_millis(150));
    child.kill().unwrap();
    let status = child.wait().unwrap();
    assert!(
        !status.success(),
        "the task finished before it was killed: make it bigger"
    );
    assert!(!tile.exists(), "a killed task left its tile");
    ok(&["batch", s(&job), "--task", "0", "-q"]);
    let resumed = bytes(&tile);
    std::fs::remove_file(&tile).unwrap();
    ok(&["batch", s(&job), "--task", "0", "-q", "--threads", "2"]);
    assert_eq!(bytes(&tile), resumed);
}

#[test]
fn bad_jobs_are_refused_with_the_place_and_the_allowed_range() {
    let dir = scratch("bad-jobs");
    let job = dir.join("job.ron");
    let cases = [
        (JOB.replace("spp: 2", "spp: 0"), "job.ron:4:"),
        (JOB.replace("spp: 2", "spq: 2"), "did you mean `spp`?"),
        (JOB.replace("tiles: 2", "tiles: 25"), "allowed: 1 to 24"),
        // Below zero or past any integer type, the field's range still.
        (
            JOB.replace("tiles: 2", "tiles: -1"),
            "`tiles` = -1 is out of range; allowed: 1 to 32768",
        ),
        (
            JOB.replace("frames: 2", "frames: 99999999999999999999999"),
            "`frames` = 99999999999999999999999 is out of range; allowed: 1 to 3600",
        ),
        (JOB.replace("frames: 2", "frames: 0"), "allowed: 1 to 3600"),
        (
            JOB.replace("spp: 2)", "spp: 2, ao_mm: Some(1e6))"),
            "`ao_mm` = 1000000 is out of range; allowed: a positive distance (mm), at most 1e5",
        ),
        (
            JOB.replace("recipes: [\"sunstone\"]", "recipes: []"),
            "`recipes` is empty",
        ),
        (JOB.replace("tiles: 2,\n)", "tiles: 2"), "job.ron:"),
        (
            JOB.replace("recipes: [\"sunstone\"]", "recipes: [\"sunstones\"]"),
            "job.ron:3:15: recipe `sunstones` does not load",
        ),
        // A task's tile of 32768 × 16384 pixels needs 67 GiB; tiles of at
        // most 978 rows fit in the 4 GiB a task may take.
        (
            JOB.replace("width: 32, height: 24", "width: 32768, height: 32768"),
            "job.ron:6:",
        ),
        (
            JOB.replace("width: 32, height: 24", "width: 32768, height: 32768"),
            "allowed: `tiles` from 34 (`tiles` = 2 now)",
        ),
        // Beside an image 24 rows high, no tile count fits both.
        (
            JOB.replace(
                "Settings(width: 32,",
                "Settings(width: 32768, height: 32768), Settings(width: 32,",
            ),
            "it needs 34 tiles, but an image 24 rows high allows at most 24",
        ),
    ];
    for (text, expected) in cases {
        std::fs::write(&job, &text).unwrap();
        let out = refused(&["batch", s(&job)], expected);
        assert!(lapidary(&["batch", s(&job)]).stdout.is_empty(), "{out}");
        if text.contains("sunstones") {
            // Named where the job names it, and what it might be; a task
            // run anyway says so too.
            assert!(out.contains("did you mean `sunstone`?"), "{out}");
            refused(&["batch", s(&job), "--task", "0", "-q"], "sunstones");
        }
    }
    std::fs::write(&job, JOB).unwrap();
    refused(&["batch", s(&job), "--task", "4"], "allowed 0 to 3");
    refused(&["batch", s(&job), "--merge"], "4 of 4 tiles are missing");
    assert!(!dir.join("out").join("sunstone-studio.png").exists());
    // With every tile there but the animation's path taken by a folder,
    // the merge writes no frame either: all images or none.
    for task in ["0", "1", "2", "3"] {
        ok(&["batch", s(&job), "--task", task, "-q"]);
    }
    // A damaged last tile stops the merge before the first frame is
    // written.
    let last = dir.join("out/tiles/sunstone-studio-0001.tile1of2.exr");
    let good = bytes(&last);
    let mut damaged = good.clone();
    let at = damaged.len() - 40;
    damaged[at] ^= 0x5a;
    std::fs::write(&last, damaged).unwrap();
    refused(
        &["batch", s(&job), "--merge", "-q"],
        "sunstone-studio-0001.tile1of2.exr",
    );
    assert!(!dir.join("out").join("sunstone-studio-0000.png").exists());
    std::fs::write(&last, good).unwrap();
    let animation = dir.join("out").join("sunstone-studio.png");
    std::fs::create_dir(&animation).unwrap();
    refused(&["batch", s(&job), "--merge", "-q"], "is a directory");
    assert!(!dir.join("out").join("sunstone-studio-0000.png").exists());
    std::fs::remove_dir(&animation).unwrap();
    ok(&["batch", s(&job), "--merge", "-q"]);
    assert!(animation.is_file() && dir.join("out").join("sunstone-studio-0001.png").is_file());
}

#[test]
fn validate_checks_a_job_and_every_recipe_and_scene_it_names() {
    let dir = scratch("validate-jobs");
    let job = dir.join("job.ron");
    std::fs::write(&job, JOB).unwrap();
    let out = lapidary(&["validate", s(&job)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let summary = String::from_utf8(out.stdout).unwrap();
    assert!(
        summary.contains("ok (job, 4 tasks: 1 image × 2 frames × 2 tiles)"),
        "{summary}"
    );
    // A scene that is a gem, and a gem file with a mistake: each named
    // where the job names it, with the file's own error after it.
    std::fs::write(dir.join("gem.ron"), "Gem(name: \"x\")\n").unwrap();
    let cases = [
        (
            JOB.replace(
                "recipes: [\"sunstone\"],",
                "recipes: [\"sunstone\"], scenes: [\"gem.ron\"],",
            ),
            "job.ron:3:38: scene",
            "where a scene (`Scene(…)`) was expected",
        ),
        (
            JOB.replace(
                "recipes: [\"sunstone\"]",
                "recipes: [\"sunstone\", \"gem.ron\"]",
            ),
            "job.ron:3:28: recipe",
            "gem.ron:1:14: missing field `surface` in Gem",
        ),
    ];
    for (text, place, nested) in cases {
        std::fs::write(&job, &text).unwrap();
        for args in [vec!["validate", s(&job)], vec!["batch", s(&job)]] {
            let out = lapidary(&args);
            let all = format!("{}{}", String::from_utf8_lossy(&out.stdout), stderr(&out));
            assert_eq!(out.status.code(), Some(1), "{args:?}: {all}");
            assert!(
                all.contains(place) && all.contains(nested),
                "{args:?}: {all}"
            );
        }
    }
}

/// `NAME = value` lines and the `queue` line of an HTCondor submit file.
fn submit_file(path: &Path) -> (Vec<(String, String)>, Option<String>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut settings = Vec::new();
    let mut queue = None;
    for line in text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
    {
        if let Some(rest) = line.strip_prefix("queue") {
            queue = Some(rest.trim().to_string());
        } else if let Some((name, value)) = line.split_once('=') {
            settings.push((name.trim().to_string(), value.trim().to_string()));
        }
    }
    (settings, queue)
}

/// `$(NAME)` macros of `text` replaced from `macros`.
fn expand(text: &str, macros: &[(String, String)]) -> String {
    macros.iter().fold(text.to_string(), |t, (name, value)| {
        t.replace(&format!("$({name})"), value)
    })
}

#[test]
fn the_htcondor_submit_files_run_the_batch_and_merge_to_the_single_render() {
    let dir = scratch("condor");
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/farm");
    std::fs::write(dir.join("job.ron"), JOB).unwrap();
    let list = lapidary(&["batch", s(&dir.join("job.ron"))]);
    assert!(list.status.success());
    std::fs::write(dir.join("tasks.txt"), &list.stdout).unwrap();
    let run = |settings: &[(String, String)], item: &[(String, String)]| {
        let mut macros = settings.to_vec();
        macros.extend_from_slice(item);
        let arguments = settings
            .iter()
            .find(|(k, _)| k == "arguments")
            .expect("arguments")
            .1
            .clone();
        let arguments = expand(&arguments, &macros);
        assert!(!arguments.contains("$("), "unexpanded: {arguments}");
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_lapidary"))
            .args(arguments.split_whitespace())
            .current_dir(&dir)
            .output()
            .unwrap();
        assert!(out.status.success(), "{arguments}: {}", stderr(&out));
    };
    // `queue task, name from tasks.txt`: one item per line, fields split
    // by whitespace, in the submit file's own words.
    let (settings, queue) = submit_file(&examples.join("lapidary.sub"));
    let queue = queue.expect("a queue line");
    let (variables, file) = queue.split_once(" from ").expect("queue … from FILE");
    let variables: Vec<&str> = variables.split(',').map(str::trim).collect();
    let items = std::fs::read_to_string(dir.join(file.trim())).unwrap();
    assert_eq!(items.lines().count(), 4);
    for line in items.lines() {
        let fields: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(fields.len(), variables.len(), "{line}");
        let item: Vec<(String, String)> = variables
            .iter()
            .zip(fields)
            .map(|(v, f)| (v.to_string(), f.to_string()))
            .collect();
        run(&settings, &item);
    }
    let (merge_settings, merge_queue) = submit_file(&examples.join("merge.sub"));
    assert_eq!(merge_queue.as_deref(), Some(""));
    run(&merge_settings, &[]);
    let dag = std::fs::read_to_string(examples.join("lapidary.dag")).unwrap();
    assert!(dag.contains("PARENT tasks CHILD merge"), "{dag}");

    let single = dir.join("single.png");
    let mut args = SMALL.to_vec();
    args.extend(["--frames", "2", "-q", "-o", s(&single)]);
    ok(&args);
    for name in ["-0000.png", "-0001.png", ".png"] {
        assert_eq!(
            bytes(&dir.join(format!("out/sunstone-studio{name}"))),
            bytes(&dir.join(format!("single{name}"))),
            "{name}"
        );
    }
    // The example job lists its tasks.
    let example = lapidary(&["batch", s(&examples.join("job.ron"))]);
    assert!(example.status.success(), "{}", stderr(&example));
    assert_eq!(
        String::from_utf8(example.stdout).unwrap().lines().count(),
        16
    );
}

#[test]
fn a_tile_is_not_written_over_another_tile_of_the_same_render() {
    // Two tiles of a two-frame turntable given one -o: the second would
    // replace the first's frames; refused before any work, the first kept.
    let dir = scratch("tile-over-tile");
    let out = dir.join("tt.exr");
    let args = |tile: &'static str| {
        vec![
            "render",
            "sunstone",
            "--size",
            "16",
            "--spp",
            "1",
            "--frames",
            "2",
            "--tile",
            tile,
            "-q",
            "-o",
            s(&out),
        ]
    };
    ok(&args("0/2"));
    let first = std::fs::read(dir.join("tt-0000.exr")).unwrap();
    refused(
        &args("1/2"),
        "holds tile 0 of 2 of this render, which tile 1 would replace",
    );
    assert_eq!(std::fs::read(dir.join("tt-0000.exr")).unwrap(), first);
    // The same tile again, or another render's tile, writes as ever.
    ok(&args("0/2"));
    let mut other = args("1/2");
    other[5] = "2";
    ok(&other);
}

#[test]
fn a_job_s_scene_warnings_are_shown_by_validate_and_batch() {
    // A scene whose stone sinks 3 mm into the ground: rendered, with the
    // warning `validate SCENE` gives, before a farm array starts.
    let dir = scratch("job-warnings");
    let scene = dir.join("sunk.ron");
    std::fs::write(
        &scene,
        r#"Scene(
    camera: Orbit(target: (0.0, 0.0, 1.0), distance: 40.0, elevation_deg: 30.0, azimuth_deg: 0.0, vertical_fov_deg: 25.0),
    stones: [Stone(shape: Cabochon(outline: Oval, length: 10.0, width: 8.0), position: (0.0, 0.0, -2.5))],
    ground: Some(Ground(height: 0.0, material: "teflon")),
)"#,
    )
    .unwrap();
    let job = dir.join("job.ron");
    std::fs::write(
        &job,
        r#"Job(output: "out", recipes: ["sunstone"], scenes: ["studio", "sunk.ron"], settings: [Settings(width: 8, height: 8, spp: 1)])"#,
    )
    .unwrap();
    let sinks = "sunk.ron: warning: stone 1 sinks 3.000 mm into the ground";
    let out = lapidary(&["validate", s(&job)]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(stderr(&out).matches(sinks).count(), 1, "{}", stderr(&out));
    assert!(ok(&["batch", s(&job)]).contains(sinks));
}

#[test]
fn a_stale_tile_stops_the_merge_before_any_image_is_written() {
    // Two images; the second's recipe file changes after its task ran.
    let dir = scratch("stale-first");
    let gem = dir.join("mine.ron");
    let text = lapidary::recipe::library::builtin_gem_source("sunstone").unwrap();
    std::fs::write(&gem, text).unwrap();
    let job = dir.join("job.ron");
    std::fs::write(
        &job,
        r#"Job(output: "out", recipes: ["sunstone", "mine.ron"], settings: [Settings(width: 8, height: 8, spp: 1)])"#,
    )
    .unwrap();
    for task in ["0", "1"] {
        ok(&["batch", s(&job), "--task", task, "-q"]);
    }
    std::fs::write(&gem, format!("{text}\n// edited\n")).unwrap();
    refused(&["batch", s(&job), "--merge"], "--task 1`)");
    // The first image's tiles are this job's, but nothing was merged.
    assert!(!dir.join("out/sunstone-studio.png").exists());
}
