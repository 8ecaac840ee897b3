//! OpenEXR's ZIP codec for blocks of one scan line (`ZIPS`), at zlib
//! level 1.
//!
//! The `exr` crate compresses its ZIP blocks at zlib level 4. On a 512²
//! render's 14 channels level 1 is three times as fast for a file 1.5 %
//! larger (issue 6: writing the EXR was a twelfth of the peer scene's whole
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

/// The zlib level of every block.
pub const ZLIB_LEVEL: u8 = 1;

/// The stored bytes of one block whose raw little-endian bytes are
/// `raw_le`: the compressed form, or `raw_le` itself when that is not
/// smaller.
pub fn encode_block(raw_le: &[u8]) -> Vec<u8> {
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
    let compressed = miniz_oxide::deflate::compress_to_vec_zlib(&predicted, ZLIB_LEVEL);
    if compressed.len() < raw_le.len() {
        compressed
    } else {
        raw_le.to_vec()
    }
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
    fn incompressible_blocks_are_stored_raw() {
        let noisy: Vec<u8> = (0..4096u64)
            .map(|i| (crate::sampling::mix64(i) >> 56) as u8)
            .collect();
        assert_eq!(encode_block(&noisy), noisy);
        let smooth = vec![0u8; 4096];
        assert!(encode_block(&smooth).len() < 100);
    }
}
