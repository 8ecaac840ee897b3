//! OpenEXR files of linear film and AOVs (albedo, normal, depth, cell ids,
//! glitter and inclusion coverage, material ids, ambient occlusion).
//!
//! One part, one layer, any number of channels with dotted names (`R`, `G`,
//! `B`, `A`, `albedo.R`, `normal.X`, `depth.Z`, `surface_cell` as U32): the
//! most portable layout, which Nuke, Blender, `exrheader` and the `exr`
//! crate all read as layers named by the prefix. Samples are stored exactly
//! (32-bit float or unsigned int) with ZIP compression of each scan line
//! (OpenEXR's `ZIPS`, at zlib level 1: `exr_zip`), so a round
//! trip is bit-exact.
//!
//! The file is encoded in memory and written with
//! [`write_atomically`](super::write_atomically): a crash or a full disk
//! never leaves a half-written EXR behind.

use std::collections::HashSet;
use std::io::Write;
use std::path::Path;

use ::exr::block::chunk::{Chunk, CompressedBlock, CompressedScanLineBlock};
use ::exr::block::writer::ChunksWriter;
use ::exr::meta::attribute::{AttributeValue, ChannelDescription, SampleType, Text};
use ::exr::meta::header::Header;
use ::exr::meta::BlockDescription;
use ::exr::prelude::{
    read, Compression, FlatSamples, IntegerBounds, LayerAttributes, LineOrder, ReadChannels,
    ReadLayers, SmallVec, Vec2,
};
use rayon::prelude::*;

use super::exr_zip;

use super::{check_writable, write_atomically_with, OutputError};
use crate::render::film::Film;

/// The samples of one channel, row-major, `width * height` of them.
#[derive(Clone, Debug, PartialEq)]
pub enum ChannelData {
    /// 32-bit float samples: radiance, albedo, normals, depth.
    F32(Vec<f32>),
    /// 32-bit unsigned samples: ids (e.g. the Voronoi cell of a surface),
    /// stored exactly where a float would lose integers above 2^24.
    U32(Vec<u32>),
}

impl ChannelData {
    /// Number of samples held.
    pub fn len(&self) -> usize {
        match self {
            ChannelData::F32(v) => v.len(),
            ChannelData::U32(v) => v.len(),
        }
    }

    /// `true` when no samples are held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One named channel of an EXR image.
#[derive(Clone, Debug, PartialEq)]
pub struct ExrChannel {
    /// Channel name, dotted for layers (`albedo.R`); printable ASCII,
    /// 1 to 255 bytes, unique within the file.
    pub name: String,
    /// The samples, row-major, `width * height` of them.
    pub data: ChannelData,
}

/// An EXR image as read back: its size and its channels sorted by name.
#[derive(Clone, Debug, PartialEq)]
pub struct ExrImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// All channels of the first layer, sorted by name (byte order, as the
    /// EXR format stores them).
    pub channels: Vec<ExrChannel>,
    /// The layer's text attributes beyond the standard ones (as
    /// [`write_exr_with_note`] writes), sorted by name; text that is not
    /// UTF-8 is decoded lossily.
    pub notes: Vec<(String, String)>,
}

/// Longest channel name the EXR format allows (with the long-names flag,
/// which the `exr` crate sets by itself above 31 bytes).
const MAX_CHANNEL_NAME_BYTES: usize = 255;

/// Write `channels` of a `width × height` image to `path` as a single-part,
/// single-layer, losslessly compressed EXR, atomically.
///
/// Refused with an [`OutputError`] naming `path` (and the channel, where one
/// is at fault): a zero width or height, no channels, an empty, duplicate,
/// over-long or non-printable-ASCII name, a channel whose sample count is not
/// `width * height`, and a path whose directory does not exist. Channels may
/// come in any order; the file stores them sorted by name.
pub fn write_exr(
    path: &Path,
    width: u32,
    height: u32,
    channels: &[ExrChannel],
) -> Result<(), OutputError> {
    write_exr_owned(path, width, height, channels.to_vec())
}

/// [`write_exr`] taking the channels by value: the samples move into the
/// encoder instead of being copied, and the compressed blocks stream into
/// the temporary file, so a render's EXR costs little memory beyond its
/// film (issue 6: peak memory).
pub fn write_exr_owned(
    path: &Path,
    width: u32,
    height: u32,
    channels: Vec<ExrChannel>,
) -> Result<(), OutputError> {
    let whole = Band {
        rows: 0..height,
        image_height_px: height,
    };
    write_exr_with_attributes(path, width, whole, channels, LayerAttributes::default())
}

/// Rows `rows` of an image `image_height_px` rows high: where a band's (a
/// tile's) pixels sit in its image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Band {
    /// The band's rows, from the image's top.
    pub rows: std::ops::Range<u32>,
    /// The whole image's height, in rows.
    pub image_height_px: u32,
}

/// [`write_exr_owned`] of the band `band` of an image (its channels hold
/// the band's rows alone), with one text attribute `note = (name, text)` in
/// the header besides the standard ones (e.g. what a tile of a render is,
/// for the merge to check). The file's data window is the band's rows of
/// its display window, the whole image, so that viewers place it there.
/// The text is stored as its UTF-8 bytes; one attribute, so the header's
/// bytes do not depend on a map's order.
pub fn write_exr_with_note(
    path: &Path,
    width: u32,
    band: Band,
    channels: Vec<ExrChannel>,
    note: (&str, &str),
) -> Result<(), OutputError> {
    let (name, text) = note;
    let name = Text::new_or_none(name)
        .filter(|n| !n.bytes().is_empty() && n.bytes().iter().all(u8::is_ascii_graphic))
        .ok_or_else(|| OutputError {
            path: path.display().to_string(),
            message: format!("attribute name {name:?} must be printable ASCII"),
        })?;
    let mut attributes = LayerAttributes::default();
    attributes.other.insert(
        name,
        AttributeValue::Text(Text::from_slice_unchecked(text.as_bytes())),
    );
    write_exr_with_attributes(path, width, band, channels, attributes)
}

fn write_exr_with_attributes(
    path: &Path,
    width: u32,
    band: Band,
    channels: Vec<ExrChannel>,
    attributes: LayerAttributes,
) -> Result<(), OutputError> {
    let err = |message: String| OutputError {
        path: path.display().to_string(),
        message,
    };
    if band.rows.end > band.image_height_px || band.rows.start > band.rows.end {
        return Err(err(format!(
            "rows {}..{} are not a band of an image {} rows high",
            band.rows.start, band.rows.end, band.image_height_px
        )));
    }
    let height = band.rows.end - band.rows.start;
    let pixel_count = validate(width, height, &channels).map_err(err)?;
    let first_row = band.rows.start as usize;
    debug_assert!(channels.iter().all(|c| c.data.len() == pixel_count));
    check_writable(path)?;

    let mut channels = channels;
    channels.sort_by(|a, b| a.name.as_bytes().cmp(b.name.as_bytes()));
    let descriptions: SmallVec<[ChannelDescription; 5]> = channels
        .iter()
        .map(|channel| {
            let name = Text::from(channel.name.as_str());
            let linear = ChannelDescription::guess_quantization_linearity(&name);
            let sample_type = match channel.data {
                ChannelData::F32(_) => SampleType::F32,
                ChannelData::U32(_) => SampleType::U32,
            };
            ChannelDescription::new(name, sample_type, linear)
        })
        .collect();
    let header = Header::new(
        Text::from(""),
        (width as usize, height as usize),
        descriptions,
    )
    .with_encoding(
        Compression::ZIP1,
        BlockDescription::ScanLines,
        LineOrder::Increasing,
    )
    .with_attributes(attributes)
    .with_display_window(IntegerBounds::new(
        (0, 0),
        (width as usize, band.image_height_px as usize),
    ))
    .with_position(Vec2(0, first_row as i32));
    let width = width as usize;
    write_atomically_with(path, |file| {
        let mut buffered = std::io::BufWriter::new(file);
        ::exr::block::write(
            &mut buffered,
            SmallVec::from_elem(header, 1),
            true,
            |_, writer| {
                // Lines in groups, each group compressed in parallel and written
                // in order: the same bytes on any number of threads, and only a
                // group's compressed lines held at once.
                let height = height as usize;
                for first in (0..height).step_by(LINES_PER_GROUP) {
                    let group = first..(first + LINES_PER_GROUP).min(height);
                    let blocks: Vec<Vec<u8>> = group
                        .clone()
                        .into_par_iter()
                        .map(|y| exr_zip::encode_block(&line_bytes(&channels, width, y)))
                        .collect();
                    for (y, compressed_pixels_le) in group.zip(blocks) {
                        let chunk = Chunk {
                            layer_index: 0,
                            compressed_block: CompressedBlock::ScanLine(CompressedScanLineBlock {
                                // Absolute: the data window starts at the band's first row.
                                y_coordinate: (first_row + y) as i32,
                                compressed_pixels_le,
                            }),
                        };
                        writer.write_chunk(y, chunk)?;
                    }
                }
                Ok(())
            },
        )
        .map_err(|e| format!("cannot encode EXR: {e}"))?;
        buffered.flush().map_err(|e| format!("cannot write: {e}"))
    })
}

/// Scan lines compressed together (in parallel) before they are written.
const LINES_PER_GROUP: usize = 64;

/// The raw bytes of scan line `y`: each channel's samples of that line in
/// turn, little-endian (the channels sorted by name, as the header lists
/// them).
fn line_bytes(channels: &[ExrChannel], width: usize, y: usize) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(channels.len() * width * 4);
    let line = y * width..(y + 1) * width;
    for channel in channels {
        match &channel.data {
            ChannelData::F32(v) => v[line.clone()]
                .iter()
                .for_each(|x| bytes.extend_from_slice(&x.to_le_bytes())),
            ChannelData::U32(v) => v[line.clone()]
                .iter()
                .for_each(|x| bytes.extend_from_slice(&x.to_le_bytes())),
        }
    }
    bytes
}

fn validate(width: u32, height: u32, channels: &[ExrChannel]) -> Result<usize, String> {
    if width == 0 || height == 0 {
        return Err(format!(
            "image size {width}×{height}: width and height must both be at least 1"
        ));
    }
    // The EXR data window is limited to i32::MAX / 2 per axis (OpenEXR).
    let max_side = (i32::MAX / 2) as u32;
    if width >= max_side || height >= max_side {
        return Err(format!(
            "image size {width}×{height}: width and height must be below {max_side}"
        ));
    }
    let pixel_count = (width as usize)
        .checked_mul(height as usize)
        .ok_or_else(|| format!("image size {width}×{height} is too large"))?;
    if channels.is_empty() {
        return Err("no channels to write: an EXR needs at least one".into());
    }
    let mut seen = HashSet::new();
    for channel in channels {
        let name = &channel.name;
        if name.is_empty() {
            return Err("channel name \"\" is empty: names must have 1 to 255 bytes".into());
        }
        if name.len() > MAX_CHANNEL_NAME_BYTES {
            return Err(format!(
                "channel name \"{name}\" has {} bytes: names must have 1 to {MAX_CHANNEL_NAME_BYTES}",
                name.len()
            ));
        }
        if !name.bytes().all(|b| b.is_ascii_graphic() || b == b' ') {
            return Err(format!(
                "channel name {name:?} must be printable ASCII (e.g. \"albedo.R\")"
            ));
        }
        if !seen.insert(name.as_str()) {
            return Err(format!(
                "channel \"{name}\" appears more than once: names must be unique"
            ));
        }
        let samples = channel.data.len();
        if samples != pixel_count {
            return Err(format!(
                "channel \"{name}\" has {samples} samples, expected {pixel_count} \
                 (width {width} × height {height})"
            ));
        }
    }
    Ok(pixel_count)
}

/// Read the first layer of the EXR at `path`, all channels, at full
/// resolution.
///
/// F32 and U32 channels come back exactly as stored; half-float (F16)
/// channels, which lapidary never writes, are widened to F32 (exact). Deep
/// images and unreadable files give an [`OutputError`] naming `path`.
pub fn read_exr(path: &Path) -> Result<ExrImage, OutputError> {
    let err = |message: String| OutputError {
        path: path.display().to_string(),
        message,
    };
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| err(format!("cannot read EXR: {e}")))?;
    let layer = image.layer_data;
    let width = u32::try_from(layer.size.width())
        .map_err(|_| err(format!("width {} is too large", layer.size.width())))?;
    let height = u32::try_from(layer.size.height())
        .map_err(|_| err(format!("height {} is too large", layer.size.height())))?;
    let mut channels: Vec<ExrChannel> = layer
        .channel_data
        .list
        .into_iter()
        .map(|channel| ExrChannel {
            name: channel.name.to_string(),
            data: match channel.sample_data {
                FlatSamples::F16(v) => ChannelData::F32(v.into_iter().map(f32::from).collect()),
                FlatSamples::F32(v) => ChannelData::F32(v),
                FlatSamples::U32(v) => ChannelData::U32(v),
            },
        })
        .collect();
    channels.sort_by(|a, b| a.name.as_bytes().cmp(b.name.as_bytes()));
    Ok(ExrImage {
        width,
        height,
        channels,
        notes: text_notes(&layer.attributes.other),
    })
}

/// The text attributes among a layer's `other` attributes, as (name,
/// text), sorted.
fn text_notes<'a>(
    attributes: impl IntoIterator<Item = (&'a exr::meta::attribute::Text, &'a AttributeValue)>,
) -> Vec<(String, String)> {
    let mut notes: Vec<(String, String)> = attributes
        .into_iter()
        .filter_map(|(name, value)| match value {
            AttributeValue::Text(text) => Some((
                name.to_string(),
                String::from_utf8_lossy(text.bytes()).into_owned(),
            )),
            _ => None,
        })
        .collect();
    notes.sort();
    notes
}
/// What the header of an EXR says, read without its pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct ExrHeader {
    /// Width of the first layer in pixels.
    pub width: u64,
    /// Height of the first layer in pixels.
    pub height: u64,
    /// Its text attributes (name, text), sorted, as [`read_exr`] gives them.
    pub notes: Vec<(String, String)>,
}

/// The header of the EXR at `path` (its layer's size and text attributes),
/// without decoding a pixel: what a file claims can be checked before
/// [`read_exr`] allocates for it. A file of several parts is refused.
pub fn read_exr_header(path: &Path) -> Result<ExrHeader, OutputError> {
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| OutputError {
        path: path.display().to_string(),
        message: format!("cannot read EXR: {e}"),
    })?;
    // One part, so that the size checked here is the layer `read_exr`
    // decodes (its first valid layer could be a later part's).
    if meta.headers.len() > 1 {
        return Err(OutputError {
            path: path.display().to_string(),
            message: format!(
                "holds {} parts, where lapidary writes one",
                meta.headers.len()
            ),
        });
    }
    let header = meta.headers.first();
    let size = header.map_or(exr::math::Vec2(0, 0), |h| h.layer_size);
    Ok(ExrHeader {
        width: size.width() as u64,
        height: size.height() as u64,
        notes: header
            .map(|header| text_notes(&header.own_attributes.other))
            .unwrap_or_default(),
    })
}

/// The EXR channels of a film: RGBA and the AOV layers, dotted names, plus
/// `ao` when `with_ao`. Takes the film so that single-valued buffers move
/// into the channels and the three-valued ones are freed as soon as split.
pub fn film_channels(film: Film, with_ao: bool) -> Vec<ExrChannel> {
    let f32_channel = |name: &str, data: Vec<f32>| ExrChannel {
        name: name.to_string(),
        data: ChannelData::F32(data),
    };
    let split = |v: Vec<[f32; 3]>, names: [&str; 3]| {
        let channels: Vec<ExrChannel> = (0..3)
            .map(|i| f32_channel(names[i], v.iter().map(|p| p[i]).collect()))
            .collect();
        drop(v);
        channels
    };
    let mut channels = split(film.rgb, ["R", "G", "B"]);
    channels.push(f32_channel("A", film.alpha));
    channels.extend(split(film.albedo, ["albedo.R", "albedo.G", "albedo.B"]));
    channels.extend(split(film.normal, ["normal.X", "normal.Y", "normal.Z"]));
    channels.push(f32_channel("depth.Z", film.depth));
    channels.push(ExrChannel {
        name: "surface_cell".to_string(),
        data: ChannelData::U32(film.surface_cell),
    });
    channels.push(f32_channel("glitter", film.glitter));
    channels.push(f32_channel("inclusion", film.inclusion));
    channels.push(ExrChannel {
        name: "material_id".to_string(),
        data: ChannelData::U32(film.material_id),
    });
    if with_ao {
        channels.push(f32_channel("ao", film.ao));
    }
    channels
}
