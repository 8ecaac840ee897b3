//! `lapidary render`: the command a user runs, its outputs and its refusals.

mod common;

use common::cli::{lapidary, lapidary_with_env, stderr};
use std::path::{Path, PathBuf};
use std::process::Command;

fn scratch(name: &str) -> common::cli::Scratch {
    common::cli::scratch("render", name)
}

/// `lapidary render ARGS -o dir/NAME -q` with the material cache in
/// `cache` and `LAPIDARY_CACHE` set to `setting` (unset for None): the
/// image's bytes.
fn render_with_cache(
    dir: &Path,
    cache: &Path,
    args: &[&str],
    name: &str,
    setting: Option<&str>,
) -> Vec<u8> {
    let out_path = dir.join(name);
    let mut command = Command::new(env!("CARGO_BIN_EXE_lapidary"));
    command.arg("render").args(args);
    command.args(["-o", out_path.to_str().unwrap(), "-q"]);
    command.env("LAPIDARY_CACHE_DIR", cache);
    match setting {
        Some(setting) => command.env("LAPIDARY_CACHE", setting),
        None => command.env_remove("LAPIDARY_CACHE"),
    };
    let out = command.output().unwrap();
    assert!(out.status.success(), "{name}: {}", stderr(&out));
    std::fs::read(out_path).unwrap()
}

/// Files left in `dir` (to prove a failed render leaves nothing behind).
fn files_in(dir: &PathBuf) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect()
}

#[test]
fn the_default_gem_renders_with_no_arguments_but_the_output() {
    let dir = scratch("default");
    let png = dir.join("gem.png");
    let out = lapidary(&[
        "render",
        "-o",
        png.to_str().unwrap(),
        "--size",
        "48",
        "--spp",
        "2",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!((img.width(), img.height()), (48, 48));
    // The stone is green aventurine: in the middle of the frame green
    // dominates red and blue.
    let (mut r, mut g, mut b) = (0u64, 0u64, 0u64);
    for y in 18..30 {
        for x in 18..30 {
            let p = img.get_pixel(x, y);
            r += u64::from(p[0]);
            g += u64::from(p[1]);
            b += u64::from(p[2]);
        }
    }
    assert!(g > r && g > b, "centre is not green: r {r} g {g} b {b}");
    assert!(
        stderr(&out).contains("Mrays/s"),
        "no speed summary: {}",
        stderr(&out)
    );
}

#[test]
fn thread_count_does_not_change_a_single_byte() {
    let dir = scratch("threads");
    let one = dir.join("one.png");
    let four = dir.join("four.png");
    for (path, threads) in [(&one, "1"), (&four, "4")] {
        let out = lapidary(&[
            "render",
            "-o",
            path.to_str().unwrap(),
            "--size",
            "32",
            "--spp",
            "3",
            "--threads",
            threads,
            "-q",
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
    }
    assert_eq!(std::fs::read(&one).unwrap(), std::fs::read(&four).unwrap());
}

#[test]
fn each_pixel_filter_renders_its_own_picture_the_same_on_any_thread_count() {
    let dir = scratch("filters");
    let render = |filter: &str, threads: &str| {
        let path = dir.join(format!("{filter}-{threads}.png"));
        let out = lapidary(&[
            "render",
            "-o",
            path.to_str().unwrap(),
            "--size",
            "24",
            "--spp",
            "3",
            "--threads",
            threads,
            "--filter",
            filter,
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
        (std::fs::read(path).unwrap(), stderr(&out))
    };
    let mut pictures = Vec::new();
    for (filter, named) in [
        ("tent", ""),
        ("box", ", box filter"),
        ("gaussian", ", Gaussian filter"),
    ] {
        let (one, report) = render(filter, "1");
        let (three, _) = render(filter, "3");
        assert_eq!(one, three, "{filter}: the thread count changed the picture");
        assert!(
            report.contains(&format!("3 spp{named})")),
            "{filter}: {report}"
        );
        pictures.push(one);
    }
    assert!(pictures[0] != pictures[1] && pictures[1] != pictures[2] && pictures[0] != pictures[2]);
    let out = lapidary(&["render", "-o", "x.png", "--filter", "mitchell"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("tent, box, gaussian"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn scene_studio_is_the_built_in_scene_and_a_gem_is_no_scene() {
    // `--scene studio` (no file of that name here) is the default scene,
    // as `validate studio` and a job's `scenes: ["studio"]` name it.
    let dir = scratch("scene-studio");
    let named = dir.join("named.png");
    let default = dir.join("default.png");
    for (path, extra) in [(&named, &["--scene", "studio"][..]), (&default, &[][..])] {
        let mut args = vec!["render", "-o", path.to_str().unwrap(), "--size", "16"];
        args.extend(["--spp", "2", "-q"]);
        args.extend(extra);
        let out = lapidary(&args);
        assert!(out.status.success(), "{}", stderr(&out));
    }
    assert_eq!(
        std::fs::read(&named).unwrap(),
        std::fs::read(&default).unwrap()
    );
    let gem = dir.join("gem.png");
    let out = lapidary(&[
        "render",
        "--scene",
        "goldstone",
        "-o",
        gem.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("`goldstone` is a built-in gem, not a scene"),
        "{}",
        stderr(&out)
    );
    assert!(!gem.exists());
}

#[test]
fn switches_in_the_environment_are_read_in_any_case_and_others_are_said_to_be_ignored() {
    let dir = scratch("switches");
    let png = dir.join("gem.png");
    let render = |name: &str, value: &str| {
        Command::new(env!("CARGO_BIN_EXE_lapidary"))
            .args(["render", "--size", "8", "--spp", "1", "-o"])
            .arg(&png)
            .env(name, value)
            .output()
            .unwrap()
    };
    let out = render("LAPIDARY_SIMD", "OFF");
    assert!(stderr(&out).contains("portable code"), "{}", stderr(&out));
    for (name, value) in [("LAPIDARY_SIMD", "0"), ("LAPIDARY_CACHE", "false")] {
        let out = render(name, value);
        assert!(out.status.success(), "{}", stderr(&out));
        assert!(
            stderr(&out).contains(&format!("warning: {name}={value} is ignored; allowed: off")),
            "{}",
            stderr(&out)
        );
    }
    let out = render("LAPIDARY_CACHE_DIR", png.to_str().unwrap());
    assert!(
        stderr(&out).contains("is not a folder: tables are kept in memory only"),
        "{}",
        stderr(&out)
    );
}

/// `lapidary render --size 8 --spp 1 -q -o OUTPUT` of the default gem,
/// which must succeed.
fn render_tiny(output: &Path) {
    let out = lapidary(&[
        "render",
        "--size",
        "8",
        "--spp",
        "1",
        "-q",
        "-o",
        output.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
}

#[test]
fn an_output_through_a_symbolic_link_replaces_the_file_it_points_to() {
    let dir = scratch("symlink");
    let (target, link) = (dir.join("target.png"), dir.join("link.png"));
    std::fs::write(&target, "old").unwrap();
    std::os::unix::fs::symlink("target.png", &link).unwrap();
    render_tiny(&link);
    assert!(link.is_symlink(), "the link was replaced by a file");
    assert_eq!(&std::fs::read(&target).unwrap()[1..4], b"PNG");
}

#[test]
fn an_output_name_of_the_longest_length_a_file_system_allows_is_written() {
    // 255 bytes: the temporary file beside it cannot add `.NAME.PID.tmp`
    // to that, so it takes a shortened name of its own.
    let dir = scratch("long-name");
    let name = format!("{}.png", "a".repeat(251));
    render_tiny(&dir.join(&name));
    assert_eq!(files_in(&dir), [name]);
}

#[test]
fn an_output_that_is_the_environment_map_read_is_refused() {
    let dir = scratch("map-as-output");
    let map = dir.join("sky.exr");
    render_tiny(&map);
    let before = std::fs::read(&map).unwrap();
    let out = lapidary(&[
        "render",
        "--env",
        map.to_str().unwrap(),
        "--size",
        "8",
        "--spp",
        "1",
        "-o",
        dir.join(".").join("sky.exr").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("the output is the environment map the render reads"),
        "{}",
        stderr(&out)
    );
    assert_eq!(
        std::fs::read(&map).unwrap(),
        before,
        "the map was written over"
    );
}

#[test]
fn the_crate_docs_steps_render_the_command_s_bytes() {
    use lapidary::render::{film, prepare};
    use lapidary::{output, scene, GemSource, TableCache, Tables};
    use std::sync::Arc;
    let dir = scratch("library");
    let (library, command) = (dir.join("library.png"), dir.join("command.png"));
    // The steps of src/lib.rs's example, for goldstone (footprints matter).
    let gem = GemSource::load("goldstone").unwrap();
    let scene = scene::default_scene();
    let cache = Arc::new(TableCache::in_memory());
    let bounces = lapidary::render::still::DEFAULT_BOUNCES;
    let mut traced = prepare::prepare_scene(
        &scene,
        &gem,
        None,
        bounces,
        Tables::Computed(&cache),
        &|_| {},
    )
    .unwrap();
    traced.shade_flakes_by_footprint(Some(Arc::clone(&cache)));
    let camera = prepare::camera_for(&scene, 24, 24);
    let settings = film::FilmSettings::new(24, 24, 4, 0);
    let film = film::render(&traced, &camera, &settings, &|_| {});
    let png = output::tonemap::DisplayTransform::default().encode(&film.rgb, 24, 24);
    output::write_png(&library, &png).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_lapidary"))
        .args([
            "render",
            "goldstone",
            "--size",
            "24",
            "--spp",
            "4",
            "-q",
            "-o",
        ])
        .arg(&command)
        .env("LAPIDARY_CACHE", "off")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(
        std::fs::read(&library).unwrap(),
        std::fs::read(&command).unwrap()
    );
    // The one call gives the same film, hence the same bytes.
    use lapidary::render::still::{render_still, StillSettings};
    let settings = StillSettings {
        width_px: 24,
        height_px: 24,
        samples_per_pixel: 4,
        ..Default::default()
    };
    let one_call = render_still(&scene, &gem, &settings).unwrap();
    assert!(
        one_call == film,
        "render_still's film differs from the steps'"
    );
    let one_call_png = dir.join("one-call.png");
    output::write_png(
        &one_call_png,
        &output::tonemap::DisplayTransform::default().encode_film(&one_call),
    )
    .unwrap();
    assert_eq!(
        std::fs::read(&one_call_png).unwrap(),
        std::fs::read(&command).unwrap()
    );
    // Settings out of range are errors naming the field and the range.
    for (settings, expected) in [
        (
            StillSettings {
                width_px: 0,
                ..settings.clone()
            },
            "width_px 0: allowed 1 to 32768 pixels",
        ),
        (
            StillSettings {
                samples_per_pixel: 0,
                ..settings.clone()
            },
            "samples_per_pixel 0: allowed 1 to 1048576",
        ),
        (
            StillSettings {
                bounces: 65,
                ..settings.clone()
            },
            "bounces 65: allowed 0 to 64",
        ),
    ] {
        let error = render_still(&scene, &gem, &settings).unwrap_err();
        assert_eq!(error.to_string(), expected);
    }
}

#[test]
fn env_replaces_a_scene_s_map_even_when_its_file_is_missing() {
    let dir = scratch("env-rescue");
    // A map to light with: any small EXR render.
    let sky = dir.join("sky.exr");
    let out = lapidary(&[
        "render",
        "--size",
        "8",
        "--spp",
        "1",
        "-q",
        "-o",
        sky.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let scene_text = |map: &str| {
        format!(
            "Scene(camera: Orbit(target: (0.0, 0.0, 1.0), distance: 40.0, elevation_deg: 30.0, azimuth_deg: 0.0, vertical_fov_deg: 25.0), \
             stones: [Stone(recipe: Some(\"sunstone\"), shape: Cabochon(outline: Oval, length: 10.0, width: 8.0), position: (0.0, 0.0, 0.5))], \
             environment: File(path: \"{map}\"))"
        )
    };
    let render = |scene: &str, name: &str| {
        let (file, png) = (
            dir.join(format!("{name}.ron")),
            dir.join(format!("{name}.png")),
        );
        std::fs::write(&file, scene).unwrap();
        let out = lapidary(&[
            "render",
            "--scene",
            file.to_str().unwrap(),
            "--env",
            sky.to_str().unwrap(),
            "--size",
            "8",
            "--spp",
            "1",
            "-q",
            "-o",
            png.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{name}: {}", stderr(&out));
        std::fs::read(&png).unwrap()
    };
    // The scene's own map missing, or present: --env lights both the same.
    assert_eq!(
        render(&scene_text("gone.hdr"), "missing"),
        render(&scene_text("sky.exr"), "present")
    );
}

#[test]
fn a_recipe_no_stone_takes_is_said_to_be_unused() {
    // Every stone of the peer scene names its own recipe.
    let dir = scratch("unused-recipe");
    let png = dir.join("peer.png");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/bench/peer-scene.ron");
    let args = ["--scene", scene, "--size", "8", "--spp", "1", "-q", "-o"];
    let mut with_recipe = vec!["render", "goldstone"];
    with_recipe.extend(args);
    with_recipe.push(png.to_str().unwrap());
    let out = lapidary(&with_recipe);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("names its own recipe: goldstone is not used"),
        "{}",
        stderr(&out)
    );
    let mut without = vec!["render"];
    without.extend(args);
    without.push(png.to_str().unwrap());
    let out = lapidary(&without);
    assert!(!stderr(&out).contains("warning"), "{}", stderr(&out));
}

#[test]
fn too_few_bounces_for_a_translucent_stone_s_inside_are_said() {
    // Goldstone's glass: its inside takes the refraction in (its flakes
    // are no bounces); an opaque gem shows its surface at 0.
    let dir = scratch("bounces-inside");
    let png = dir.join("gem.png");
    let warned = |gem: &str, bounces: &str| {
        let out = lapidary(&[
            "render",
            gem,
            "--size",
            "8",
            "--spp",
            "1",
            "-q",
            "--bounces",
            bounces,
            "-o",
            png.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
        stderr(&out).contains("its body and flakes need --bounces 1 or more")
    };
    assert!(warned("goldstone", "0"));
    assert!(!warned("goldstone", "1"));
    assert!(!warned("sunstone", "0"));
}

#[test]
fn footprints_by_default_and_exact_flakes_on_request_and_neither_with_the_thread_count() {
    // Goldstone's copper at 32 px: about a hundred flakes to a pixel, and
    // any met after a flake's reflection, so by default some are shaded by
    // their lobe and `--exact-flakes` shades each by its own normal (other
    // bytes); each image is a pure function of the settings.
    let dir = scratch("footprints");
    let render = |name: &str, extra: &[&str]| {
        let path = dir.join(name);
        let mut args = vec![
            "render",
            "goldstone",
            "-o",
            path.to_str().unwrap(),
            "--size",
            "32",
            "--spp",
            "2",
            "-q",
        ];
        args.extend_from_slice(extra);
        let out = lapidary(&args);
        assert!(out.status.success(), "{}", stderr(&out));
        std::fs::read(&path).unwrap()
    };
    let one = render("one.png", &["--threads", "1"]);
    let two = render("two.png", &["--threads", "2"]);
    let exact_one = render("exact-one.png", &["--exact-flakes", "--threads", "1"]);
    let exact_two = render("exact-two.png", &["--exact-flakes", "--threads", "2"]);
    assert_eq!(one, two);
    assert_eq!(exact_one, exact_two);
    assert_ne!(one, exact_one);
}

#[test]
fn the_seed_changes_the_noise() {
    let dir = scratch("seed");
    let a = dir.join("a.png");
    let b = dir.join("b.png");
    for (path, seed) in [(&a, "1"), (&b, "2")] {
        let out = lapidary(&[
            "render",
            "-o",
            path.to_str().unwrap(),
            "--size",
            "24",
            "--spp",
            "1",
            "--seed",
            seed,
            "-q",
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
    }
    assert_ne!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}

#[test]
fn an_exr_reads_back_with_rgba_and_every_aov_layer() {
    let dir = scratch("exr");
    let exr = dir.join("gem.exr");
    let out = lapidary(&[
        "render",
        "-o",
        exr.to_str().unwrap(),
        "--width",
        "20",
        "--height",
        "12",
        "--spp",
        "2",
        "-q",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let image = lapidary::output::exr::read_exr(&exr).unwrap();
    assert_eq!((image.width, image.height), (20, 12));
    let names: Vec<&str> = image.channels.iter().map(|c| c.name.as_str()).collect();
    for wanted in [
        "R",
        "G",
        "B",
        "A",
        "albedo.R",
        "albedo.G",
        "albedo.B",
        "normal.X",
        "normal.Y",
        "normal.Z",
        "depth.Z",
        "surface_cell",
        "glitter",
        "inclusion",
        "material_id",
    ] {
        assert!(
            names.contains(&wanted),
            "missing channel {wanted} in {names:?}"
        );
    }
    // The default scene has a ground under the stone: every pixel sees a
    // surface, the ground has material id 1 and the stone ids ≥ 2.
    let ids = image
        .channels
        .iter()
        .find(|c| c.name == "material_id")
        .map(|c| match &c.data {
            lapidary::output::exr::ChannelData::U32(v) => v.clone(),
            lapidary::output::exr::ChannelData::F32(_) => panic!("material_id must be U32"),
        })
        .unwrap();
    assert!(ids.contains(&1), "no ground pixel");
    assert!(ids.iter().any(|id| *id >= 2), "no stone pixel");
    // Inclusion coverage is a fraction, and none where nothing was hit.
    let alpha = exr_f32(&image, "A");
    for (coverage, alpha) in exr_f32(&image, "inclusion").iter().zip(&alpha) {
        assert!((0.0..=1.0).contains(coverage));
        assert!(*alpha > 0.0 || *coverage == 0.0, "inclusions in the sky");
    }
}

#[test]
fn the_inclusion_layer_shows_where_a_translucent_stone_has_flakes() {
    // The benchmark's goldstone glass (copper platelets at depth) in the
    // studio scene: the layer is the fraction of samples that refracted
    // in and met a flake first, > 0 on the stone and 0 on the ground.
    let dir = scratch("inclusion");
    let exr = dir.join("goldstone.exr");
    let recipe = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("bench/translucent-goldstone.ron");
    let out = lapidary(&[
        "render",
        recipe.to_str().unwrap(),
        "-o",
        exr.to_str().unwrap(),
        "--size",
        "24",
        "--spp",
        "4",
        "-q",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let image = lapidary::output::exr::read_exr(&exr).unwrap();
    let coverage = exr_f32(&image, "inclusion");
    let ids = match &image
        .channels
        .iter()
        .find(|c| c.name == "material_id")
        .unwrap()
        .data
    {
        lapidary::output::exr::ChannelData::U32(v) => v.clone(),
        lapidary::output::exr::ChannelData::F32(_) => panic!("material_id must be U32"),
    };
    assert!(coverage.iter().all(|c| (0.0..=1.0).contains(c)));
    // The first sample of a pixel with id 1 or 0 missed the stone; its
    // other samples may not have (a pixel on the outline), so only the
    // pixels away from the stone are checked for 0: the frame's corners.
    let size = 24;
    for corner in [0, size - 1, size * (size - 1), size * size - 1] {
        assert!(ids[corner] < 2, "corner {corner} is on the stone");
        assert_eq!(coverage[corner], 0.0, "corner {corner}");
    }
    let on_stone: Vec<f32> = coverage
        .iter()
        .zip(&ids)
        .filter(|(_, id)| **id >= 2)
        .map(|(c, _)| *c)
        .collect();
    assert!(!on_stone.is_empty(), "no stone pixel");
    let mean = on_stone.iter().sum::<f32>() / on_stone.len() as f32;
    assert!(mean > 0.2, "mean coverage over the stone {mean}");
}

#[test]
fn bad_settings_are_refused_before_any_work_and_leave_no_file() {
    let dir = scratch("bad");
    let png = dir.join("x.png");
    let p = png.to_str().unwrap();
    let (jpg, missing, hdr, ron) = (
        dir.join("x.jpg"),
        dir.join("missing/x.png"),
        dir.join("nope.hdr"),
        dir.join("nope.ron"),
    );
    let (jpg, missing, hdr, ron) = (
        jpg.to_str().unwrap(),
        missing.to_str().unwrap(),
        hdr.to_str().unwrap(),
        ron.to_str().unwrap(),
    );
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["render", "-o", p, "--size", "0"],
            "--size 0: allowed 1 to",
        ),
        (
            vec!["render", "-o", p, "--height", "0"],
            "--height 0: allowed 1 to",
        ),
        (vec!["render", "-o", p, "--spp", "0"], "--spp 0"),
        (
            vec!["render", "-o", p, "--width", "30000", "--height", "30000"],
            "GiB",
        ),
        (vec!["render", "-o", p, "--threads", "0"], "--threads 0"),
        (vec!["render", "-o", jpg, "--size", "8"], ".png or .exr"),
        (
            vec!["render", "no-such-gem", "-o", p, "--size", "8"],
            "no-such-gem",
        ),
        (vec!["render", "-o", missing, "--size", "8"], "missing"),
        (
            vec!["render", "-o", p, "--size", "8", "--env", hdr],
            "nope.hdr",
        ),
        (
            vec!["render", "-o", p, "--size", "8", "--scene", ron],
            "nope.ron",
        ),
    ];
    for (args, needle) in cases {
        let out = lapidary(&args);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {}", stderr(&out));
        assert!(
            stderr(&out).contains(needle),
            "{args:?}: message lacks {needle:?}: {}",
            stderr(&out)
        );
        assert!(!stderr(&out).contains("panicked"), "{args:?}");
    }
    assert!(
        files_in(&dir).is_empty(),
        "left behind: {:?}",
        files_in(&dir)
    );
}

#[test]
fn a_corrupt_environment_or_scene_is_an_error_naming_the_file() {
    let dir = scratch("corrupt");
    let hdr = dir.join("broken.hdr");
    std::fs::write(&hdr, b"#?RADIANCE\nthis is not an image").unwrap();
    let scene = dir.join("scene.ron");
    std::fs::write(
        &scene,
        "Scene(camera: Orbit(target: (0, 0, 0), distance: -5.0))",
    )
    .unwrap();
    let png = dir.join("x.png");
    for args in [
        vec![
            "render",
            "-o",
            png.to_str().unwrap(),
            "--size",
            "8",
            "--env",
            hdr.to_str().unwrap(),
        ],
        vec![
            "render",
            "-o",
            png.to_str().unwrap(),
            "--size",
            "8",
            "--scene",
            scene.to_str().unwrap(),
        ],
    ] {
        let out = lapidary(&args);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {}", stderr(&out));
        let named = if args.contains(&"--env") {
            "broken.hdr"
        } else {
            "scene.ron"
        };
        assert!(stderr(&out).contains(named), "{}", stderr(&out));
    }
    assert!(!png.exists());
}

fn exr_f32(image: &lapidary::output::exr::ExrImage, name: &str) -> Vec<f32> {
    match &image
        .channels
        .iter()
        .find(|c| c.name == name)
        .unwrap_or_else(|| panic!("no {name}"))
        .data
    {
        lapidary::output::exr::ChannelData::F32(v) => v.clone(),
        lapidary::output::exr::ChannelData::U32(_) => panic!("{name} is not F32"),
    }
}

#[test]
fn ambient_occlusion_is_an_extra_layer_that_leaves_the_beauty_alone() {
    let dir = scratch("ao");
    let plain = dir.join("plain.exr");
    let with_ao = dir.join("ao.exr");
    for (path, extra) in [(&plain, vec![]), (&with_ao, vec!["--ao", "6"])] {
        let mut args = vec![
            "render",
            "-o",
            path.to_str().unwrap(),
            "--size",
            "24",
            "--spp",
            "4",
            "-q",
        ];
        args.extend(extra);
        let out = lapidary(&args);
        assert!(out.status.success(), "{}", stderr(&out));
    }
    let plain = lapidary::output::exr::read_exr(&plain).unwrap();
    let with_ao = lapidary::output::exr::read_exr(&with_ao).unwrap();
    for c in ["R", "G", "B"] {
        assert_eq!(
            exr_f32(&plain, c),
            exr_f32(&with_ao, c),
            "beauty channel {c} changed"
        );
    }
    assert!(!plain.channels.iter().any(|c| c.name == "ao"));
    let ao = exr_f32(&with_ao, "ao");
    assert!(ao.iter().all(|a| (0.0..=1.0).contains(a)));
    // The ground far from the stone is open sky (the frame corners), the
    // ground where the stone meets it is enclosed.
    assert_eq!(ao[0], 1.0, "top-left corner sees only sky");
    let min = ao.iter().cloned().fold(1.0, f32::min);
    assert!(min < 0.75, "nowhere occluded (min {min})");
    // Its PNG is the occlusion as it is: --exposure and --tonemap (the
    // beauty's) leave its bytes alone, and the summary says what it shows.
    let png = |name: &str, extra: &[&str]| {
        let path = dir.join(name);
        let mut args = vec![
            "render",
            "-o",
            path.to_str().unwrap(),
            "--size",
            "16",
            "--spp",
            "2",
            "--ao",
            "6",
        ];
        args.extend(extra);
        let out = lapidary(&args);
        assert!(out.status.success(), "{}", stderr(&out));
        (std::fs::read(&path).unwrap(), stderr(&out))
    };
    let (plain_png, summary) = png("ao.png", &[]);
    assert!(
        summary.contains("ambient occlusion within 6 mm"),
        "{summary}"
    );
    assert_eq!(png("ao-ev.png", &["--exposure", "5"]).0, plain_png);
    assert_eq!(png("ao-linear.png", &["--tonemap", "linear"]).0, plain_png);
}

#[test]
fn ctrl_c_stops_a_long_render_promptly_and_writes_nothing() {
    let dir = scratch("interrupt");
    let png = dir.join("long.png");
    // About a minute of work on two cores if it were not interrupted.
    let child = Command::new(env!("CARGO_BIN_EXE_lapidary"))
        .args([
            "render",
            "-o",
            png.to_str().unwrap(),
            "--size",
            "512",
            "--spp",
            "128",
            "-q",
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(2500));
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("interrupted"), "{}", stderr(&out));
    assert!(
        files_in(&dir).is_empty(),
        "left behind: {:?}",
        files_in(&dir)
    );
    // Exit 1 with "interrupted" and no file means the render stopped
    // before it finished (a finished render exits 0 and writes the PNG).
}

#[test]
fn the_material_cache_never_changes_a_byte_cold_warm_off_or_damaged() {
    // Green aventurine's flake materials go through the random walk, so
    // their tables are real computations, not the closed form.
    let dir = scratch("cache");
    let cache = dir.join("cache");
    let render = |name: &str, setting: Option<&str>| {
        render_with_cache(&dir, &cache, &["--size", "24", "--spp", "1"], name, setting)
    };
    let off = render("off.png", Some("off"));
    assert!(!cache.exists(), "LAPIDARY_CACHE=off wrote a cache");
    let cold = render("cold.png", None);
    let tables = files_in(&cache);
    assert!(!tables.is_empty(), "a cold render fills the cache");
    let warm = render("warm.png", None);
    // Damage every table: the renderer must notice and recompute.
    for name in &tables {
        std::fs::write(cache.join(name), "compensation table, damaged\n1 2 3").unwrap();
    }
    let damaged = render("damaged.png", None);
    assert!(off == cold && cold == warm && warm == damaged);
}

#[test]
fn the_glitter_facets_tables_never_change_a_byte_cold_warm_off_or_damaged() {
    // Fine glitter at 24 px: every pixel's footprint holds hundreds of
    // facets, so the render builds its facets' table (render::glitter_aggregate)
    // and a cold render keeps it as a file of numbers.
    let dir = scratch("glitter-cache");
    let cache = dir.join("cache");
    let gem = dir.join("fine-glitter.ron");
    std::fs::write(&gem, include_str!("../bench/fine-glitter.ron")).unwrap();
    let args = [gem.to_str().unwrap(), "--size", "24", "--spp", "4"];
    let render =
        |name: &str, setting: Option<&str>| render_with_cache(&dir, &cache, &args, name, setting);
    let off = render("off.png", Some("off"));
    let cold = render("cold.png", None);
    let tables: Vec<String> = files_in(&cache)
        .into_iter()
        .filter(|name| name.starts_with("values-"))
        .collect();
    assert_eq!(
        tables.len(),
        1,
        "one glitter material, one table: {tables:?}"
    );
    let warm = render("warm.png", None);
    // Cut the table short: the renderer must notice and build it again.
    let file = cache.join(&tables[0]);
    let bytes = std::fs::read(&file).unwrap();
    std::fs::write(&file, &bytes[..bytes.len() - 5]).unwrap();
    let damaged = render("damaged.png", None);
    assert!(off == cold && cold == warm && warm == damaged);
}

#[test]
fn the_vector_code_path_writes_the_same_bytes_as_the_portable_one() {
    // `LAPIDARY_SIMD=off` runs the portable copy of the row loop; the
    // default runs the best copy the CPU has (the summary line names
    // which). EXR with ambient occlusion: every AOV and every optional ray
    // of the integrator is compared. 21 spp: a full batch of 16 samples
    // (the vector Sobol and camera code) and a partial one (point by
    // point). The default studio scene and the benchmark's peer scene
    // (its bare Lambert ground and sphere lights).
    let dir = scratch("simd");
    let peer = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("bench/peer-scene.ron");
    for (name, scene) in [("studio", None), ("peer", Some(peer))] {
        let default = dir.join(format!("{name}-default.exr"));
        let portable = dir.join(format!("{name}-portable.exr"));
        let mut summaries = Vec::new();
        for (path, env) in [
            (&default, &[][..]),
            (&portable, &[("LAPIDARY_SIMD", "off")][..]),
        ] {
            let mut args = vec![
                "render",
                "-o",
                path.to_str().unwrap(),
                "--ao",
                "2",
                "--spp",
                "21",
                "--size",
                "32",
            ];
            if let Some(scene) = &scene {
                args.extend(["--scene", scene.to_str().unwrap()]);
            }
            let out = lapidary_with_env(&args, env);
            assert!(out.status.success(), "{}", stderr(&out));
            summaries.push(stderr(&out));
        }
        assert!(
            summaries[1].contains("portable code"),
            "LAPIDARY_SIMD=off ran: {}",
            summaries[1]
        );
        assert!(
            ["x86-64-v3 code", "portable code"]
                .iter()
                .any(|code| summaries[0].contains(code)),
            "no code path named: {}",
            summaries[0]
        );
        let bytes = |path: &std::path::Path| std::fs::read(path).unwrap();
        assert!(
            bytes(&default) == bytes(&portable),
            "{name}: the copies differ"
        );
    }
}

#[test]
fn a_map_with_a_sun_is_reported_as_sampled_apart_and_a_smooth_one_is_not() {
    let dir = scratch("sun-map");
    // A 64 × 32 sky with a one-texel sun of 97 % of its power, and the
    // same sky without it.
    let sky = |_col: usize, row: usize| if row < 16 { [0.5, 0.6, 0.8] } else { [0.1; 3] };
    let (sunny, plain) = (dir.join("sunny.hdr"), dir.join("plain.hdr"));
    common::maps::write_hdr(&sunny, 64, 32, |col, row| {
        if (col, row) == (10, 5) {
            [2.0e4; 3]
        } else {
            sky(col, row)
        }
    });
    common::maps::write_hdr(&plain, 64, 32, sky);
    let out_png = dir.join("out.png");
    let report = |map: &std::path::Path| {
        let args = [
            "render",
            "-o",
            out_png.to_str().unwrap(),
            "--size",
            "8",
            "--spp",
            "1",
            "--env",
            map.to_str().unwrap(),
        ];
        let out = lapidary(&args);
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        stderr(&out)
    };
    let sunny_report = report(&sunny);
    assert!(
        sunny_report.contains("environment map: its brightest texel holds 9"),
        "{sunny_report}"
    );
    assert!(!report(&plain).contains("sampled apart"));
}
