//! Per-pixel flags, one byte per pixel (the `flags` map, an 8-bit TIFF).
//!
//! A flag says how to trust a pixel's values; only [`HOT`] changes what the
//! pipeline does (stage 0 masks it). Several flags may be set at once.

/// Hot: the pixel's dark counts alone would cross the threshold (SPAD, see
/// [`super::HotCriterion`]), or its dark level stands far above the others
/// (frame cameras). The hot-pixel mask is exactly this set.
pub const HOT: u8 = 1 << 0;
/// Read 1 in every bit-plane of the dark recording (SPAD) or clipped at 0 or
/// 65535 ADU in some dark or flat frame (frame cameras): the stored rate is a
/// finite lower estimate.
pub const SATURATED: u8 = 1 << 1;
/// SPAD: no dark count in the whole recording; the stored rate is 0 and the
/// true rate is below `ln 20/(n·τ)` at 95 % confidence. Not a defect by
/// itself: a flat tells whether the pixel is dead.
pub const NO_COUNTS: u8 = 1 << 2;
/// Responds to light with less than the dead fraction of the median pixel
/// (from a flat; never set without one).
pub const DEAD: u8 = 1 << 3;
/// SPAD: read 1 in every plane of the flat, so its PRNU is a lower estimate.
pub const FLAT_SATURATED: u8 = 1 << 4;
/// Frame cameras: read noise more than 3× the median (e.g. random telegraph noise).
pub const NOISY: u8 = 1 << 5;
/// The estimate could not be formed from the data (e.g. a frame camera pixel
/// without a measurable photon-transfer slope); the stored value is the
/// median of the other pixels.
pub const UNMEASURED: u8 = 1 << 6;

/// Every flag defined in version 1 of the format; other bits are an error.
pub const ALL: u8 = HOT | SATURATED | NO_COUNTS | DEAD | FLAT_SATURATED | NOISY | UNMEASURED;

/// Names of the flags set in `f`, for reports and CSV files (`HOT|DEAD`).
pub fn names(f: u8) -> String {
    let table = [
        (HOT, "HOT"),
        (SATURATED, "SATURATED"),
        (NO_COUNTS, "NO_COUNTS"),
        (DEAD, "DEAD"),
        (FLAT_SATURATED, "FLAT_SATURATED"),
        (NOISY, "NOISY"),
        (UNMEASURED, "UNMEASURED"),
    ];
    let v: Vec<&str> = table
        .iter()
        .filter(|(b, _)| f & b != 0)
        .map(|&(_, n)| n)
        .collect();
    if v.is_empty() {
        "-".to_string()
    } else {
        v.join("|")
    }
}

/// Number of pixels with flag `bit` set.
pub fn count(flags: &[u8], bit: u8) -> usize {
    flags.iter().filter(|&&f| f & bit != 0).count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_counts() {
        assert_eq!(names(0), "-");
        assert_eq!(names(HOT | SATURATED), "HOT|SATURATED");
        assert_eq!(count(&[HOT, 0, HOT | DEAD, DEAD], HOT), 2);
        assert_eq!(ALL, 0x7f);
    }
}
