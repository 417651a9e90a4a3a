//! The words the hosts stream: planes as 32-bit pipe words and as P-pixel
//! stream words, and pipe-in bytes as whole 16-byte blocks of words.

use smartagg_model::plane::BitPlane;

/// Pipe words of planes: 32 pixels a word, pixel i of the stream in bit i.
pub fn pipe_words(planes: &[BitPlane]) -> Vec<u32> {
    let mut words = Vec::new();
    let mut acc = 0u32;
    let mut n = 0;
    for p in planes {
        for b in p.bits().iter().by_vals() {
            acc |= (b as u32) << n;
            n += 1;
            if n == 32 {
                words.push(acc);
                acc = 0;
                n = 0;
            }
        }
    }
    if n > 0 {
        words.push(acc);
    }
    words
}

/// Stream word `idx` (P pixels) of a plane.
pub(super) fn stream_word(plane: &BitPlane, p: usize, idx: usize) -> u64 {
    let bits = plane.bits();
    let mut w = 0u64;
    for i in 0..p {
        if bits[idx * p + i] {
            w |= 1 << i;
        }
    }
    w
}

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
