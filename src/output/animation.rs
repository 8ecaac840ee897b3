//! Animated PNG (APNG) of a turntable's frames, for web pages: every
//! browser plays it, and a viewer without APNG support shows the first
//! frame as a still.

use std::path::Path;

use super::{write_atomically, OutputError};

/// Write `frames` (equal sizes, shown in order, looping for ever) as an
/// animated PNG at `frames_per_second`, atomically. Refused with an
/// [`OutputError`] naming `path`: no frames, frames of different sizes,
/// a rate outside 1 to 100 frames per second, or a failed write.
pub fn write_apng(
    path: &Path,
    frames: &[image::RgbImage],
    frames_per_second: u16,
) -> Result<(), OutputError> {
    let err = |message: String| OutputError {
        path: path.display().to_string(),
        message,
    };
    let first = frames
        .first()
        .ok_or_else(|| err("an animation needs at least one frame".into()))?;
    let (width, height) = first.dimensions();
    if let Some((k, _)) = frames
        .iter()
        .enumerate()
        .find(|(_, f)| f.dimensions() != (width, height))
    {
        return Err(err(format!(
            "frame {k} is {}×{}, frame 0 is {width}×{height}: every frame must be the same size",
            frames[k].width(),
            frames[k].height()
        )));
    }
    if !(1..=100).contains(&frames_per_second) {
        return Err(err(format!(
            "{frames_per_second} frames per second: allowed 1 to 100"
        )));
    }
    let frame_count = u32::try_from(frames.len())
        .map_err(|_| err(format!("{} frames are too many", frames.len())))?;
    let encode = || -> Result<Vec<u8>, png::EncodingError> {
        let mut bytes = Vec::new();
        let mut encoder = png::Encoder::new(&mut bytes, width, height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        // 0 plays: loop for ever, as a turntable on a page should.
        encoder.set_animated(frame_count, 0)?;
        encoder.set_frame_delay(1, frames_per_second)?;
        let mut writer = encoder.write_header()?;
        for frame in frames {
            writer.write_image_data(frame.as_raw())?;
        }
        writer.finish()?;
        Ok(bytes)
    };
    let bytes = encode().map_err(|e| err(format!("cannot encode APNG: {e}")))?;
    write_atomically(path, &bytes)
}
