//! OpenEXR's ZIP codec for blocks of one scan line (`ZIPS`), at zlib
//! level 1.
//!
//! The `exr` crate compresses its ZIP blocks at zlib level 4. On a
//! render's 14 channels level 1 is several times as fast for a file about
//! 1.5 % larger (writing the EXR is otherwise a noticeable part of a whole
//! run), and any reader decodes both alike: the level is the encoder's
//! choice alone (OpenEXR itself makes it a setting).
//!
//! The codec (OpenEXR's `ImfZip.cpp`, which the `exr` crate follows): the
//! block's bytes (per line, per channel in name order, little-endian
//! samples) are split into the even-indexed bytes followed by the odd ones,
//! each byte after the first is replaced by its difference to the one
//! before plus 128 (mod 256), and the result is zlib-compressed. A block
//! that would not shrink is stored raw, as OpenEXR does: a reader tells the
//! two apart by the size.

use std::cell::RefCell;

use miniz_oxide::deflate::core::{
    compress, create_comp_flags_from_zip_params, CompressorOxide, TDEFLFlush, TDEFLStatus,
};

/// The zlib level of every block.
pub(crate) const ZLIB_LEVEL: u8 = 1;

/// The stored bytes of one block whose raw little-endian bytes are
/// `raw_le`: the compressed form, or `raw_le` itself when that is not
/// smaller.
pub(crate) fn encode_block(raw_le: &[u8]) -> Vec<u8> {
    // Loops over whole slices without a dependency from one byte to the
    // next, so that they vectorise (a third of the time of byte-by-byte
    // loops).
    let len = raw_le.len();
    if len == 0 {
        return Vec::new(); // nothing compresses below zero bytes
    }
    let half = len.div_ceil(2);
    let mut split = vec![0u8; len];
    let (even, odd) = split.split_at_mut(half);
    for ((pair, e), o) in raw_le
        .chunks_exact(2)
        .zip(even.iter_mut())
        .zip(odd.iter_mut())
    {
        *e = pair[0];
        *o = pair[1];
    }
    if len % 2 == 1 {
        even[half - 1] = raw_le[len - 1];
    }
    let mut predicted = split.clone();
    for ((difference, current), previous) in
        predicted.iter_mut().skip(1).zip(&split[1..]).zip(&split)
    {
        *difference = current.wrapping_sub(*previous).wrapping_add(128);
    }
    zlib_shorter_than(&predicted, len).unwrap_or_else(|| raw_le.to_vec())
}

thread_local! {
    /// This thread's zlib compressor, reset for each block. A new one per
    /// block (what `miniz_oxide::deflate::compress_to_vec_zlib` makes)
    /// allocates and zeroes ≈ 300 kB of tables for a 30 kB line: the
    /// zeroing and its page faults are a large part of the cost of
    /// compressing the line. The same bytes either way.
    static COMPRESSOR: RefCell<Box<CompressorOxide>> = RefCell::new(Box::new(
        CompressorOxide::new(create_comp_flags_from_zip_params(
            i32::from(ZLIB_LEVEL),
            ZLIB_WRAPPER,
            DEFAULT_STRATEGY,
        )),
    ));
}

/// miniz's `window_bits` flag for the zlib header and Adler-32 trailer
/// (what `compress_to_vec_zlib` passes).
const ZLIB_WRAPPER: i32 = 1;
/// miniz's default match-finding strategy.
const DEFAULT_STRATEGY: i32 = 0;

/// `data` zlib-compressed at [`ZLIB_LEVEL`] (the bytes of
/// `miniz_oxide::deflate::compress_to_vec_zlib`), or None when they would
/// not be shorter than `limit`: the compressor writes into `limit` − 1
/// bytes and stops where they run out.
fn zlib_shorter_than(data: &[u8], limit: usize) -> Option<Vec<u8>> {
    COMPRESSOR.with(|cell| {
        let mut compressor = cell.borrow_mut();
        compressor.reset();
        let mut output = vec![0u8; limit.saturating_sub(1)];
        let (status, bytes_in, bytes_out) =
            compress(&mut compressor, data, &mut output, TDEFLFlush::Finish);
        match status {
            TDEFLStatus::Done if bytes_in == data.len() => {
                output.truncate(bytes_out);
                Some(output)
            }
            _ => None, // out of room: the block is stored raw
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The inverse, written from the format's description: inflate, undo
    /// the differences, interleave the halves.
    fn decode_block(stored: &[u8], raw_len: usize) -> Vec<u8> {
        if stored.len() == raw_len {
            return stored.to_vec();
        }
        let mut predicted = miniz_oxide::inflate::decompress_to_vec_zlib(stored).unwrap();
        for i in 1..predicted.len() {
            predicted[i] = predicted[i]
                .wrapping_add(predicted[i - 1])
                .wrapping_sub(128);
        }
        let half = raw_len.div_ceil(2);
        (0..raw_len)
            .map(|i| {
                if i % 2 == 0 {
                    predicted[i / 2]
                } else {
                    predicted[half + i / 2]
                }
            })
            .collect()
    }

    #[test]
    fn blocks_decode_to_their_bytes() {
        let smooth: Vec<u8> = (0..4000u32)
            .flat_map(|i| (i as f32 * 0.01).to_le_bytes())
            .collect();
        let noisy: Vec<u8> = (0..4001u64)
            .map(|i| (crate::sampling::mix64(i) >> 56) as u8)
            .collect();
        for raw in [smooth, noisy, vec![7u8], Vec::new()] {
            let stored = encode_block(&raw);
            assert_eq!(decode_block(&stored, raw.len()), raw);
        }
    }

    #[test]
    fn a_reused_compressor_makes_the_bytes_of_a_new_one() {
        // Blocks of different data and sizes through this thread's one
        // compressor, each as miniz's own fresh `compress_to_vec_zlib`
        // makes it: `reset` leaves nothing of the block before.
        let smooth: Vec<u8> = (0..6000u32)
            .flat_map(|i| ((i as f32 * 0.003).sin()).to_le_bytes())
            .collect();
        let short: Vec<u8> = (0..300u32).map(|i| (i % 7) as u8).collect();
        for data in [&smooth, &short, &smooth] {
            let fresh = miniz_oxide::deflate::compress_to_vec_zlib(data, ZLIB_LEVEL);
            assert_eq!(zlib_shorter_than(data, data.len()), Some(fresh));
        }
        // A limit the compressed form reaches gives None, one above it the bytes.
        let fresh = miniz_oxide::deflate::compress_to_vec_zlib(&smooth, ZLIB_LEVEL);
        assert_eq!(zlib_shorter_than(&smooth, fresh.len()), None);
        assert_eq!(zlib_shorter_than(&smooth, fresh.len() + 1), Some(fresh));
    }

    #[test]
    fn incompressible_blocks_are_stored_raw() {
        let noisy: Vec<u8> = (0..4096u64)
            .map(|i| (crate::sampling::mix64(i) >> 56) as u8)
            .collect();
        assert_eq!(encode_block(&noisy), noisy);
        let smooth = vec![0u8; 4096];
        assert!(encode_block(&smooth).len() < 100);
    }
}
