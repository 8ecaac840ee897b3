//! Merging the tiles of a render back into its image: every tile checked
//! against its own record (size, pixel checksum), the tiles against each
//! other (one render, one split, each tile once, none missing), then the
//! rows put back in order. The result is the single render's film, bit for
//! bit; its PNG is encoded from the whole film, as a single render's is.

use std::path::{Path, PathBuf};

use crate::file_kind::not_a_regular_file;
use crate::output::exr::{read_exr, read_exr_header, ChannelData, ExrChannel, ExrHeader};
use crate::output::tonemap::DisplayTransform;
use crate::render::still::MAX_SIDE_PX;
use crate::render::tiles::TileSplit;

use super::record::{differing_line, pixels_sha256, ReadRecord, TILE_NOTE};

/// A tile read from its file and checked against its own record.
#[derive(Clone, Debug)]
pub struct Tile {
    /// The file it was read from.
    pub path: PathBuf,
    /// Its record.
    pub record: ReadRecord,
    /// Its channels, sorted by name.
    pub channels: Vec<ExrChannel>,
}

/// The record of the tile EXR at `path`, from its header alone (its pixels
/// are neither read nor checked: [`read_tile`] does both).
pub fn read_tile_record(path: &Path) -> Result<ReadRecord, String> {
    Ok(read_tile_header(path)?.1)
}

/// The header of the tile EXR at `path` and the record in it, checked
/// against each other before a pixel is read: a record whose image is
/// larger than a render can be, or a file whose size is not the tile's
/// the record describes, is refused here, so that no damaged header makes
/// [`read_tile`] allocate for pixels that no render wrote.
fn read_tile_header(path: &Path) -> Result<(ExrHeader, ReadRecord), String> {
    let name = path.display();
    if let Some(kind) = not_a_regular_file(path) {
        return Err(format!("{name}: is {kind}, not a tile file"));
    }
    let header =
        read_exr_header(path).map_err(|e| format!("{e} (a damaged or unfinished tile?)"))?;
    let record = record_in(path, &header.notes)?;
    let (width, height) = record.size_px;
    if !(1..=MAX_SIDE_PX).contains(&width) || !(1..=MAX_SIDE_PX).contains(&height) {
        return Err(format!(
            "{name}: damaged: its record says the image is {width}×{height} pixels; allowed: 1 to {MAX_SIDE_PX} a side"
        ));
    }
    let (index, count) = record.tile;
    let split = TileSplit::new(index, count, height)
        .map_err(|e| format!("{name}: damaged: its record says {e}"))?;
    let rows = split.rows();
    let tile_height = rows.end - rows.start;
    if (header.width, header.height) != (u64::from(width), u64::from(tile_height)) {
        return Err(format!(
            "{name}: damaged: it is {}×{} pixels, but tile {index} of {count} of a {width}×{height} image is {width}×{tile_height}",
            header.width, header.height
        ));
    }
    Ok((header, record))
}

/// The tile record among the EXR text attributes `notes` of the file at
/// `path`; the errors name the file.
fn record_in(path: &Path, notes: &[(String, String)]) -> Result<ReadRecord, String> {
    let name = path.display();
    let Some((_, text)) = notes.iter().find(|(k, _)| k == TILE_NOTE) else {
        return Err(format!(
            "{name}: not a lapidary tile (no `{TILE_NOTE}` record; tiles come from `lapidary render --tile I/N`)"
        ));
    };
    ReadRecord::parse(text).map_err(|e| format!("{name}: damaged: its tile record: {e}"))
}

/// Read the tile EXR at `path` and check it: a lapidary tile record, the
/// size the record says (from the header, before the pixels are
/// decoded), and pixels matching the checksum written with them. Errors
/// name the file and what is wrong.
pub fn read_tile(path: &Path) -> Result<Tile, String> {
    let name = path.display();
    if !path.exists() {
        return Err(format!("{name}: no such tile file"));
    }
    let (header, record) = read_tile_header(path)?;
    let image = read_exr(path).map_err(|e| format!("{e} (a damaged or unfinished tile?)"))?;
    // The pixels decoded are the header's (checked against the record); a
    // file changed between the two reads is caught here or by the checksum.
    if (u64::from(image.width), u64::from(image.height)) != (header.width, header.height) {
        return Err(format!(
            "{name}: damaged: its pixels are not the tile its header describes"
        ));
    }
    if pixels_sha256(&image.channels) != record.pixels_sha256 {
        return Err(format!(
            "{name}: damaged: its pixels do not match the checksum written with them"
        ));
    }
    Ok(Tile {
        path: path.to_path_buf(),
        record,
        channels: image.channels,
    })
}

/// A render rebuilt from its tiles.
#[derive(Clone, Debug, PartialEq)]
pub struct Merged {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The whole film's channels, sorted by name: what the single render's
    /// EXR holds.
    pub channels: Vec<ExrChannel>,
    /// How its PNG is encoded.
    pub display: DisplayTransform,
    /// Whether its PNG pictures the ambient occlusion, not the beauty.
    pub ao_picture: bool,
    /// Samples left out over all tiles.
    pub bad_samples: u64,
}

impl Merged {
    /// The PNG image of the merged film, encoded as a single render's
    /// (on the current rayon pool; the bytes do not depend on it).
    pub fn png_image(&self) -> image::RgbImage {
        let f32s = |name: &str| match self.channels.iter().find(|c| c.name == name) {
            Some(ExrChannel {
                data: ChannelData::F32(v),
                ..
            }) => v.as_slice(),
            _ => &[],
        };
        let pixels: Vec<[f32; 3]> = if self.ao_picture {
            f32s("ao").iter().map(|a| [*a, *a, *a]).collect()
        } else {
            let (r, g, b) = (f32s("R"), f32s("G"), f32s("B"));
            r.iter()
                .zip(g)
                .zip(b)
                .map(|((r, g), b)| [*r, *g, *b])
                .collect()
        };
        self.display.encode(&pixels, self.width, self.height)
    }
}

/// Merge checked tiles into their image. Refused, naming the files: no
/// tiles, tiles of different renders (the first setting that differs is
/// named) or splits, a tile given twice, tiles missing, channels that
/// differ.
pub fn merge(mut tiles: Vec<Tile>) -> Result<Merged, String> {
    let Some(first) = tiles.first() else {
        return Err("no tiles to merge".into());
    };
    let (first_path, first_record) = (first.path.display().to_string(), first.record.clone());
    let (count, names) = (first_record.tile.1, channel_layout(&first.channels));
    for tile in &tiles[1..] {
        let path = tile.path.display();
        if let Some(((key, theirs), (_, ours))) =
            differing_line(&tile.record.render_lines, &first_record.render_lines)
        {
            return Err(format!(
                "{path} belongs to another render than {first_path}: its {key} is {theirs}, not {ours}"
            ));
        }
        if tile.record.tile.1 != count {
            return Err(format!(
                "{path} is a tile of {}, {first_path} a tile of {count}: the tiles come from different splits",
                tile.record.tile.1
            ));
        }
        if channel_layout(&tile.channels) != names {
            return Err(format!(
                "{path} has other channels than {first_path}: {} against {}",
                channel_layout(&tile.channels).join(" "),
                names.join(" ")
            ));
        }
    }
    tiles.sort_by_key(|t| t.record.tile.0);
    if let Some(pair) = tiles
        .windows(2)
        .find(|p| p[0].record.tile.0 == p[1].record.tile.0)
    {
        return Err(format!(
            "tile {} of {count} is given twice: {} and {}",
            pair[0].record.tile.0,
            pair[0].path.display(),
            pair[1].path.display()
        ));
    }
    // The tiles are sorted and distinct: tile i is missing where fewer
    // than i + 1 tiles have numbers up to i.
    let mut given = tiles.iter().map(|t| t.record.tile.0).peekable();
    let missing: Vec<u32> = (0..count)
        .filter(|i| given.next_if_eq(i).is_none())
        .collect();
    if !missing.is_empty() {
        const LISTED: usize = 12;
        let mut listed: Vec<String> = missing.iter().take(LISTED).map(u32::to_string).collect();
        if missing.len() > LISTED {
            listed.push(format!("… ({} in all)", missing.len()));
        }
        return Err(format!(
            "tile{} {} of {count} {} missing (tiles count from 0): the image would be incomplete",
            if missing.len() == 1 { "" } else { "s" },
            listed.join(", "),
            if missing.len() == 1 { "is" } else { "are" },
        ));
    }
    let (width, height) = first_record.size_px;
    let bad_samples = tiles.iter().map(|t| t.record.bad_samples).sum();
    let mut channels: Vec<ExrChannel> = tiles[0]
        .channels
        .iter()
        .map(|c| ExrChannel {
            name: c.name.clone(),
            data: match c.data {
                ChannelData::F32(_) => ChannelData::F32(Vec::new()),
                ChannelData::U32(_) => ChannelData::U32(Vec::new()),
            },
        })
        .collect();
    for tile in tiles {
        for (all, part) in channels.iter_mut().zip(tile.channels) {
            match (&mut all.data, part.data) {
                (ChannelData::F32(all), ChannelData::F32(part)) => all.extend(part),
                (ChannelData::U32(all), ChannelData::U32(part)) => all.extend(part),
                _ => unreachable!("channel types were compared above"),
            }
        }
    }
    let (display, ao_picture) = first_record.display;
    Ok(Merged {
        width,
        height,
        channels,
        display,
        ao_picture,
        bad_samples,
    })
}

/// Each channel as `name:type`, in order.
fn channel_layout(channels: &[ExrChannel]) -> Vec<String> {
    channels
        .iter()
        .map(|c| {
            let kind = match c.data {
                ChannelData::F32(_) => "f32",
                ChannelData::U32(_) => "u32",
            };
            format!("{}:{kind}", c.name)
        })
        .collect()
}
