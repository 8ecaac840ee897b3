//! Display transform (exposure, tone curve, sRGB, dither) and EXR files.
//!
//! Expected sRGB values come from IEC 61966-2-1 itself (the formula is
//! written out again here, and its published decoding threshold 0.04045 is
//! used to check the encoding threshold); dither statistics come from the
//! fact that rounding `v + u` with `u` uniform on `(−½, ½)` has mean `v`.

use std::path::PathBuf;

use lapidary::output::exr::{read_exr, write_exr, ChannelData, ExrChannel};
use lapidary::output::tonemap::{filmic, srgb_encode, DisplayTransform, ToneCurve};

/// IEC 61966-2-1 encoding, written independently of the library.
fn srgb_reference(l: f64) -> f64 {
    if l <= 0.0031308 {
        12.92 * l
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

/// IEC 61966-2-1 decoding (the inverse), for choosing inputs by code value.
fn srgb_decode_reference(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

fn linear(seed: u64) -> DisplayTransform {
    DisplayTransform {
        exposure_ev: 0.0,
        curve: ToneCurve::Linear,
        dither_seed: seed,
    }
}

fn flat(value: f32, width: u32, height: u32) -> Vec<[f32; 3]> {
    vec![[value; 3]; (width * height) as usize]
}

fn mean_code(image: &image::RgbImage) -> f64 {
    let bytes = image.as_raw();
    bytes.iter().map(|&b| b as f64).sum::<f64>() / bytes.len() as f64
}

/// A fresh, empty directory for one test.
fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "lapidary-output-formats-{name}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn entries(dir: &std::path::Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

// ---------------------------------------------------------------- sRGB ----

#[test]
fn srgb_encode_maps_black_and_white_to_themselves() {
    assert_eq!(srgb_encode(0.0), 0.0);
    assert!((srgb_encode(1.0) - 1.0).abs() < 1e-12);
    // Out-of-range display values clamp instead of overshooting.
    assert!((srgb_encode(4.0) - 1.0).abs() < 1e-12);
    assert_eq!(srgb_encode(-1.0), 0.0);
}

#[test]
fn srgb_encode_is_continuous_at_the_standard_threshold() {
    // IEC 61966-2-1 decodes with a linear segment up to 0.04045, the image
    // of the encoding threshold 0.0031308 under both branches.
    let t = 0.0031308;
    assert!(
        (srgb_encode(t) - 0.04045).abs() < 1e-6,
        "{}",
        srgb_encode(t)
    );
    // The standard's rounded constants leave a jump of 2.9e-8 between the
    // branches (12.92·t = 0.040449936, 1.055·t^(1/2.4) − 0.055 = 0.040449907),
    // a ten-thousandth of one 8-bit code.
    assert!((srgb_encode(t * (1.0 + 1e-9)) - srgb_encode(t)).abs() < 1e-7);
    assert!((srgb_encode(t * (1.0 - 1e-9)) - srgb_encode(t)).abs() < 1e-7);
    // Linear branch below: slope 12.92.
    assert!((srgb_encode(0.001) - 0.01292).abs() < 1e-12);
}

#[test]
fn srgb_encode_matches_the_standard_formula() {
    for i in 0..=1000 {
        let l = i as f64 / 1000.0;
        assert!((srgb_encode(l) - srgb_reference(l)).abs() < 1e-12, "at {l}");
    }
}

#[test]
fn black_is_zero_and_white_is_255_for_every_dither_seed() {
    for seed in [0, 1, 0xdead_beef] {
        let black = linear(seed).encode(&flat(0.0, 16, 16), 16, 16);
        assert!(black.as_raw().iter().all(|&b| b == 0));
        let white = linear(seed).encode(&flat(1.0, 16, 16), 16, 16);
        assert!(white.as_raw().iter().all(|&b| b == 255));
    }
}

#[test]
fn half_linear_encodes_to_code_188_within_one() {
    // sRGB(0.5) = 0.7354 → 187.52 codes: rounding gives the well-known 188;
    // dither of less than half a code can only give 187 or 188, and on
    // average 187.52.
    let image = linear(3).encode(&flat(0.5, 64, 64), 64, 64);
    assert!(image.as_raw().iter().all(|&b| b == 187 || b == 188));
    let expected = 255.0 * srgb_reference(0.5);
    assert!((expected - 187.52).abs() < 0.01);
    let mean = mean_code(&image);
    assert!((mean - expected).abs() < 0.03, "mean {mean} vs {expected}");
}

// ------------------------------------------------------------ exposure ----

#[test]
fn plus_one_ev_doubles_the_value_before_the_curve() {
    // Scaling an f32 by 2 is exact, so 0.2 at +1 EV and 0.4 at 0 EV are the
    // same number entering the curve: bytes must be identical (same dither).
    for curve in [ToneCurve::Linear, ToneCurve::Filmic] {
        for (value, doubled) in [(0.2f32, 0.4f32), (0.09, 0.18), (0.35, 0.7)] {
            let at = |ev: f64, v: f32| {
                DisplayTransform {
                    exposure_ev: ev,
                    curve,
                    dither_seed: 9,
                }
                .encode(&flat(v, 8, 8), 8, 8)
            };
            assert_eq!(at(1.0, value), at(0.0, doubled), "{curve:?} {value}");
            assert_eq!(at(-1.0, doubled), at(0.0, value), "{curve:?} {value}");
            assert_ne!(at(0.0, value), at(0.0, doubled), "{curve:?} {value}");
        }
    }
}

// -------------------------------------------------------------- curves ----

#[test]
fn filmic_maps_zero_to_zero_and_stays_below_one() {
    assert_eq!(filmic(0.0), 0.0);
    let mut x = 1e-6;
    while x < 1e9 {
        let y = filmic(x);
        assert!(y > 0.0 && y < 1.0, "filmic({x}) = {y}");
        x *= 1.01;
    }
    assert!(filmic(f64::MAX) <= 1.0);
}

#[test]
fn filmic_is_monotone() {
    let mut previous = 0.0;
    for i in 1..200_000 {
        let x = i as f64 * 1e-4; // 0 … 20, finer than one 8-bit code
        let y = filmic(x);
        assert!(y > previous, "filmic not increasing at {x}");
        previous = y;
    }
    let mut x: f64 = 20.0;
    while x < 1e8 {
        let y = filmic(x);
        assert!(y >= previous, "filmic decreasing at {x}");
        previous = y;
        x *= 1.05;
    }
}

#[test]
fn filmic_keeps_mid_grey_mid_and_compresses_highlights() {
    let grey = filmic(0.18);
    assert!((0.14..=0.25).contains(&grey), "mid-grey → {grey}");
    // A shoulder: twice the light gives less than twice the display value
    // above mid-grey, and very bright highlights approach white.
    assert!(filmic(2.0) < 2.0 * filmic(1.0));
    assert!(filmic(1000.0) > 0.99);
}

#[test]
fn filmic_encode_of_mid_grey_lands_on_its_code() {
    let t = DisplayTransform {
        exposure_ev: 0.0,
        curve: ToneCurve::Filmic,
        dither_seed: 1,
    };
    let image = t.encode(&flat(0.18, 8, 8), 8, 8);
    let ideal = 255.0 * srgb_reference(filmic(0.18f32 as f64));
    for &b in image.as_raw() {
        assert!((b as f64 - ideal).abs() < 1.0, "{b} vs {ideal}");
    }
}

#[test]
fn linear_curve_clamps_to_white() {
    let width = 4;
    let pixels = vec![[1.0, 1.5, 100.0], [2.0, 0.0, 1.0], [0.0; 3], [1e30; 3]];
    let image = linear(5).encode(&pixels, width, 1);
    assert_eq!(image.get_pixel(0, 0).0, [255, 255, 255]);
    assert_eq!(image.get_pixel(1, 0).0, [255, 0, 255]);
    assert_eq!(image.get_pixel(2, 0).0, [0, 0, 0]);
    assert_eq!(image.get_pixel(3, 0).0, [255, 255, 255]);
}

#[test]
fn nan_inf_and_negative_pixels_become_black() {
    let pixels = vec![
        [f32::NAN, 0.5, f32::NAN],
        [f32::INFINITY, f32::NEG_INFINITY, -1.0],
        [1.0, 1.0, 1.0],
    ];
    for curve in [ToneCurve::Linear, ToneCurve::Filmic] {
        let t = DisplayTransform {
            exposure_ev: 0.0,
            curve,
            dither_seed: 0,
        };
        let image = t.encode(&pixels, 3, 1);
        let [r, g, b] = image.get_pixel(0, 0).0;
        assert_eq!((r, b), (0, 0), "{curve:?}");
        assert!(g > 100, "the finite channel beside a NaN survives ({g})");
        assert_eq!(image.get_pixel(1, 0).0, [0, 0, 0], "{curve:?}");
        assert!(image.get_pixel(2, 0).0.iter().all(|&c| c > 100));
    }
}

// -------------------------------------------------------------- dither ----

#[test]
fn same_seed_gives_identical_bytes_and_another_seed_differs() {
    // A flat field half-way between two codes: the dither decides every byte.
    let between = srgb_decode_reference(120.5 / 255.0) as f32;
    let pixels = flat(between, 32, 32);
    let a = linear(11).encode(&pixels, 32, 32);
    let b = linear(11).encode(&pixels, 32, 32);
    let c = linear(12).encode(&pixels, 32, 32);
    assert_eq!(a.as_raw(), b.as_raw());
    assert_ne!(a.as_raw(), c.as_raw());
    assert!(a.as_raw().iter().all(|&v| v == 120 || v == 121));
    // Neither seed collapses to one code: the field is really dithered.
    assert!(a.as_raw().contains(&120) && a.as_raw().contains(&121));
}

#[test]
fn dither_is_unbiased_on_a_flat_field() {
    // Code 100.3: a plain rounding gives 100 everywhere (bias −0.3); an
    // unbiased dither averages to 100.3. The standard deviation of the mean
    // of 3·65536 Bernoulli(0.3) codes is 0.0011, far inside 0.02.
    for target in [100.3, 37.81] {
        let value = srgb_decode_reference(target / 255.0) as f32;
        let exact = 255.0 * srgb_reference(value as f64);
        let image = linear(77).encode(&flat(value, 256, 256), 256, 256);
        let mean = mean_code(&image);
        assert!((mean - exact).abs() < 0.02, "mean {mean} vs {exact}");
    }
}

#[test]
fn dithered_ramp_follows_the_gradient_without_steps() {
    // A ramp from code 100 to 101 across 256 columns: without dither each
    // column is 100 or 101 (errors up to 0.5 code, one visible step); with
    // dither every column averages to its own value.
    let (width, height) = (256u32, 256u32);
    let ramp: Vec<f32> = (0..width)
        .map(|x| {
            let code = 100.0 + x as f64 / (width - 1) as f64;
            srgb_decode_reference(code / 255.0) as f32
        })
        .collect();
    let targets: Vec<f64> = ramp
        .iter()
        .map(|&v| 255.0 * srgb_reference(v as f64))
        .collect();
    let pixels: Vec<[f32; 3]> = (0..height)
        .flat_map(|_| ramp.iter().map(|&v| [v; 3]))
        .collect();
    let image = linear(2).encode(&pixels, width, height);
    for x in 0..width {
        let column: f64 = (0..height)
            .map(|y| image.get_pixel(x, y).0[1] as f64)
            .sum::<f64>()
            / height as f64;
        // σ of a column mean ≤ 0.5/16 = 0.031 codes.
        assert!(
            (column - targets[x as usize]).abs() < 0.16,
            "column {x}: {column} vs {}",
            targets[x as usize]
        );
    }
}

// ----------------------------------------------------------------- EXR ----

fn sample_channels(width: usize, height: usize) -> Vec<ExrChannel> {
    let n = width * height;
    let f = |name: &str, k: f32| ExrChannel {
        name: name.into(),
        data: ChannelData::F32((0..n).map(|i| (i as f32 + 0.1) * k).collect()),
    };
    let mut special: Vec<f32> = (0..n).map(|i| i as f32 * -1.37e-3).collect();
    // Values a lossy or half-float path would change.
    special[0] = f32::MIN_POSITIVE / 8.0; // subnormal
    special[1] = f32::MAX;
    special[2] = -0.0;
    special[3] = 1.0 + f32::EPSILON;
    special[4] = f32::INFINITY;
    let mut cells: Vec<u32> = (0..n as u32)
        .map(|i| i.wrapping_mul(2_654_435_761))
        .collect();
    cells[0] = u32::MAX;
    cells[1] = (1 << 24) + 1; // not representable as f32
    vec![
        f("R", 1.0),
        f("G", 0.5),
        f("B", 0.25),
        f("A", 1.0 / 3.0),
        f("albedo.R", 0.7),
        ExrChannel {
            name: "normal.X".into(),
            data: ChannelData::F32(special),
        },
        f("depth.Z", 11.0),
        ExrChannel {
            name: "surface_cell".into(),
            data: ChannelData::U32(cells),
        },
    ]
}

fn bits(data: &ChannelData) -> Vec<u32> {
    match data {
        ChannelData::F32(v) => v.iter().map(|x| x.to_bits()).collect(),
        ChannelData::U32(v) => v.clone(),
    }
}

#[test]
fn exr_round_trip_is_bit_exact_and_sorted_by_name() {
    let dir = scratch_dir("roundtrip");
    let path = dir.join("aov.exr");
    // 7×19: odd width, more rows than one 16-line ZIP block.
    let (width, height) = (7u32, 19u32);
    let written = sample_channels(width as usize, height as usize);
    write_exr(&path, width, height, &written).unwrap();
    let read = read_exr(&path).unwrap();
    assert_eq!((read.width, read.height), (width, height));
    let names: Vec<&str> = read.channels.iter().map(|c| c.name.as_str()).collect();
    // Byte order: capitals before lower case.
    assert_eq!(
        names,
        [
            "A",
            "B",
            "G",
            "R",
            "albedo.R",
            "depth.Z",
            "normal.X",
            "surface_cell"
        ]
    );
    for channel in &written {
        let back = read
            .channels
            .iter()
            .find(|c| c.name == channel.name)
            .unwrap();
        assert_eq!(
            std::mem::discriminant(&back.data),
            std::mem::discriminant(&channel.data),
            "{} changed type",
            channel.name
        );
        assert_eq!(bits(&back.data), bits(&channel.data), "{}", channel.name);
    }
    // Atomic write leaves no temporary file beside the result.
    assert_eq!(entries(&dir), ["aov.exr"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn exr_overwrites_an_existing_file() {
    let dir = scratch_dir("overwrite");
    let path = dir.join("a.exr");
    let one = |v: f32| {
        vec![ExrChannel {
            name: "depth.Z".into(),
            data: ChannelData::F32(vec![v; 6]),
        }]
    };
    write_exr(&path, 3, 2, &one(1.0)).unwrap();
    write_exr(&path, 3, 2, &one(2.0)).unwrap();
    let read = read_exr(&path).unwrap();
    assert_eq!(read.channels[0].data, ChannelData::F32(vec![2.0; 6]));
    assert_eq!(entries(&dir), ["a.exr"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn exr_refuses_a_channel_of_the_wrong_length_naming_it() {
    let dir = scratch_dir("length");
    let path = dir.join("bad.exr");
    let mut channels = sample_channels(4, 3);
    channels[4].data = ChannelData::F32(vec![0.0; 11]); // albedo.R, one short
    let e = write_exr(&path, 4, 3, &channels).unwrap_err().to_string();
    assert!(e.contains("albedo.R"), "{e}");
    assert!(e.contains("11") && e.contains("12"), "{e}");
    assert!(e.contains("bad.exr"), "{e}");
    assert!(entries(&dir).is_empty());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn exr_refuses_duplicate_and_empty_names() {
    let dir = scratch_dir("names");
    let path = dir.join("bad.exr");
    let mut channels = sample_channels(3, 2);
    channels[1].name = "normal.X".into();
    let e = write_exr(&path, 3, 2, &channels).unwrap_err().to_string();
    assert!(
        e.contains("\"normal.X\"") && e.contains("more than once"),
        "{e}"
    );

    let mut channels = sample_channels(3, 2);
    channels[2].name = String::new();
    let e = write_exr(&path, 3, 2, &channels).unwrap_err().to_string();
    assert!(e.contains("empty"), "{e}");

    let mut channels = sample_channels(3, 2);
    channels[0].name = "albédo.R".into();
    let e = write_exr(&path, 3, 2, &channels).unwrap_err().to_string();
    assert!(e.contains("albédo.R") && e.contains("ASCII"), "{e}");
    assert!(entries(&dir).is_empty());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_band_outside_its_image_is_refused() {
    // Rows 3..9 of an image 5 rows high is no band of it: refused, nothing
    // written.
    use lapidary::output::exr::{write_exr_with_note, Band};
    let dir = scratch_dir("band");
    let path = dir.join("band.exr");
    let channels = vec![ExrChannel {
        name: "R".into(),
        data: ChannelData::F32(vec![0.0; 12]),
    }];
    let band = Band {
        rows: 3..9,
        image_height_px: 5,
    };
    let e = write_exr_with_note(&path, 2, band, channels, ("note", "text"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("rows 3..9 are not a band of an image 5 rows high"),
        "{e}"
    );
    assert!(entries(&dir).is_empty());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn exr_refuses_zero_size_and_no_channels() {
    let dir = scratch_dir("zero");
    let path = dir.join("bad.exr");
    let e = write_exr(&path, 0, 3, &[]).unwrap_err().to_string();
    assert!(e.contains("0×3") && e.contains("at least 1"), "{e}");
    let channels = vec![ExrChannel {
        name: "R".into(),
        data: ChannelData::F32(vec![]),
    }];
    let e = write_exr(&path, 5, 0, &channels).unwrap_err().to_string();
    assert!(e.contains("5×0"), "{e}");
    let e = write_exr(&path, 2, 2, &[]).unwrap_err().to_string();
    assert!(e.contains("no channels"), "{e}");
    assert!(entries(&dir).is_empty());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn exr_into_a_missing_directory_fails_and_leaves_nothing() {
    let dir = scratch_dir("missing");
    let missing = dir.join("no-such-dir");
    let path = missing.join("out.exr");
    let e = write_exr(&path, 3, 2, &sample_channels(3, 2))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("does not exist") && e.contains("no-such-dir"),
        "{e}"
    );
    assert!(!missing.exists());
    assert!(entries(&dir).is_empty(), "left behind: {:?}", entries(&dir));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn read_exr_of_a_missing_or_foreign_file_is_an_error() {
    let dir = scratch_dir("read");
    let e = read_exr(&dir.join("absent.exr")).unwrap_err().to_string();
    assert!(e.contains("absent.exr"), "{e}");
    let text = dir.join("not.exr");
    std::fs::write(&text, b"this is not an OpenEXR file").unwrap();
    let e = read_exr(&text).unwrap_err().to_string();
    assert!(
        e.contains("not.exr") && e.contains("cannot read EXR"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The file the `exr` crate's own writer makes of `channels` (ZIP of one
/// scan line, at its zlib level 4): the reference for ours.
fn write_with_the_exr_crate(path: &std::path::Path, width: usize, channels: &[ExrChannel]) {
    use exr::prelude::*;
    let height = channels[0].data.len() / width;
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = channels
        .iter()
        .map(|c| {
            let samples = match &c.data {
                ChannelData::F32(v) => FlatSamples::F32(v.clone()),
                ChannelData::U32(v) => FlatSamples::U32(v.clone()),
            };
            AnyChannel::new(c.name.as_str(), samples)
        })
        .collect();
    let encoding = Encoding {
        compression: Compression::ZIP1,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let layer = Layer::new(
        (width, height),
        LayerAttributes::default(),
        encoding,
        AnyChannels::sort(list),
    );
    Image::from_layer(layer).write().to_file(path).unwrap();
}

/// Everything the `exr` crate reads from `path`: attributes, encoding,
/// channel descriptions and samples, as text.
fn decoded(path: &std::path::Path) -> String {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(path)
        .unwrap();
    format!("{image:?}")
}

#[test]
fn exr_files_match_the_exr_crates_own_writer_on_any_thread_count() {
    let dir = scratch_dir("reference-writer");
    // The AOV-like channels, and one channel of random bits alone (every
    // line incompressible: stored raw).
    let noise: Vec<u32> = (0..64 * 40u64)
        .map(|i| (lapidary::sampling::mix64(i) >> 32) as u32)
        .collect();
    let cases = [
        sample_channels(64, 40),
        vec![ExrChannel {
            name: "noise".into(),
            data: ChannelData::U32(noise),
        }],
    ];
    for (case, channels) in cases.iter().enumerate() {
        let reference = dir.join(format!("reference-{case}.exr"));
        write_with_the_exr_crate(&reference, 64, channels);
        let mut files = Vec::new();
        for threads in [1, 4] {
            let ours = dir.join(format!("ours-{case}-{threads}.exr"));
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| write_exr(&ours, 64, 40, channels).unwrap());
            // The same header, encoding and samples as the crate's file.
            assert_eq!(decoded(&ours), decoded(&reference), "case {case}");
            files.push(std::fs::read(&ours).unwrap());
        }
        assert_eq!(
            files[0], files[1],
            "case {case}: bytes depend on the thread count"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
