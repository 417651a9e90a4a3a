//! Pipe-in bytes as whole 16-byte blocks of words. (Planes as pipe words
//! and as P-pixel stream words are the model's:
//! `smartagg_model::registers::replay_words`, `BitPlane::stream_word`.)

/// Pipe-in bytes as 32-bit little-endian words in whole 16-byte blocks
/// (the end zero-padded), as the block-throttled pipe-ins take them.
pub fn block_words(bytes: &[u8]) -> Vec<u32> {
    let mut words: Vec<u32> = bytes
        .chunks(4)
        .map(|c| {
            let mut b = [0u8; 4];
            b[..c.len()].copy_from_slice(c);
            u32::from_le_bytes(b)
        })
        .collect();
    words.resize(words.len().div_ceil(4) * 4, 0);
    words
}
