//! Environment map files the tests write.

/// Writes a `w × h` Radiance HDR at `path` whose texel (col, row) is
/// `f(col, row)` (row 0 straight up).
pub fn write_hdr(path: &std::path::Path, w: usize, h: usize, f: impl Fn(usize, usize) -> [f32; 3]) {
    let pixels: Vec<image::Rgb<f32>> = (0..h)
        .flat_map(|row| (0..w).map(move |col| (col, row)))
        .map(|(col, row)| image::Rgb(f(col, row)))
        .collect();
    let file = std::fs::File::create(path).unwrap();
    image::codecs::hdr::HdrEncoder::new(std::io::BufWriter::new(file))
        .encode(&pixels, w, h)
        .unwrap();
}
