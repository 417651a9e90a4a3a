//! Pipe-in bytes as whole 16-byte blocks of words. (Bytes and planes as pipe
//! words and planes as P-pixel stream words are the model's:
//! `smartagg_model::registers::{pipe_words, replay_words}`,
//! `BitPlane::stream_word`.)

/// Pipe-in bytes as 32-bit little-endian words in whole 16-byte blocks
/// (the end zero-padded), as the block-throttled pipe-ins take them.
pub fn block_words(bytes: &[u8]) -> Vec<u32> {
    let mut words = smartagg_model::registers::pipe_words(bytes);
    words.resize(words.len().div_ceil(4) * 4, 0);
    words
}
