//! ROIs and what is known about their pixels: photo-response non-uniformity,
//! dark counts, sCMOS read-noise variance, and pixels to leave out (hot pixels,
//! pixels outside the sensor).

use crate::error::LocalizeError;
use crate::psf::MAX_SIDE;

/// Per-pixel knowledge about an ROI, row-major like its data.
///
/// All maps have `side²` entries. [`PixelMaps::uniform`] gives the neutral
/// maps (gain 1, no dark, no read noise, nothing ignored).
#[derive(Clone, Debug, PartialEq)]
pub struct PixelMaps {
    /// ROI side, pixels.
    pub side: usize,
    /// Relative detection efficiency (photo-response non-uniformity); 1 is
    /// nominal. It scales emitter *and* background light, not dark counts.
    pub gain: Vec<f64>,
    /// Known expected dark counts in the ROI data (same units as the data:
    /// photons for frame fits; for the SPAD binomial fit, counts per bit-plane).
    pub dark: Vec<f64>,
    /// sCMOS read-noise variance per pixel in photo-electrons²; used only by
    /// the sCMOS noise model.
    pub read_var: Vec<f64>,
    /// Pixels left out of the likelihood (hot pixels, pixels off the sensor).
    pub ignore: Vec<bool>,
}

impl PixelMaps {
    /// Neutral maps for an ROI of the given side.
    pub fn uniform(side: usize) -> PixelMaps {
        let n = side * side;
        PixelMaps {
            side,
            gain: vec![1.0; n],
            dark: vec![0.0; n],
            read_var: vec![0.0; n],
            ignore: vec![false; n],
        }
    }

    /// Checks sizes and values: gains finite and positive, dark and read
    /// variance finite and non-negative.
    pub fn validate(&self) -> Result<(), LocalizeError> {
        let n = self.side * self.side;
        for (name, len) in [
            ("gain", self.gain.len()),
            ("dark", self.dark.len()),
            ("read-variance", self.read_var.len()),
            ("ignore", self.ignore.len()),
        ] {
            if len != n {
                return Err(LocalizeError::MapShape {
                    map: name,
                    len,
                    expected: n,
                });
            }
        }
        if let Some(&g) = self.gain.iter().find(|g| !(g.is_finite() && **g > 0.0)) {
            return Err(LocalizeError::InvalidOption {
                name: "gain map",
                value: g,
                why: "every relative efficiency must be finite and greater than zero".into(),
            });
        }
        for (name, map) in [
            ("dark map", &self.dark),
            ("read-variance map", &self.read_var),
        ] {
            if let Some(&v) = map.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
                return Err(LocalizeError::InvalidOption {
                    name,
                    value: v,
                    why: "every value must be finite and not negative".into(),
                });
            }
        }
        Ok(())
    }

    /// Number of pixels left out.
    pub fn ignored(&self) -> usize {
        self.ignore.iter().filter(|&&b| b).count()
    }
}

/// A borrowed ROI: `side × side` values, row-major, top-left pixel first.
#[derive(Clone, Copy, Debug)]
pub struct RoiView<'a> {
    /// ROI side, pixels.
    pub side: usize,
    /// Pixel values (photons, or detections for SPAD ROIs).
    pub data: &'a [f64],
    /// Optional per-pixel maps.
    pub maps: Option<&'a PixelMaps>,
}

impl<'a> RoiView<'a> {
    /// Wraps data of side `side`, checking the shape and the maps.
    pub fn new(
        side: usize,
        data: &'a [f64],
        maps: Option<&'a PixelMaps>,
    ) -> Result<Self, LocalizeError> {
        check_shape(side, data.len())?;
        if let Some(m) = maps {
            if m.side != side {
                return Err(LocalizeError::MapShape {
                    map: "pixel",
                    len: m.side * m.side,
                    expected: side * side,
                });
            }
            m.validate()?;
        }
        Ok(RoiView { side, data, maps })
    }
}

/// Checks `len == side²` and `1 ≤ side ≤ MAX_SIDE`.
pub fn check_shape(side: usize, len: usize) -> Result<(), LocalizeError> {
    if side == 0 || side > MAX_SIDE || len != side * side {
        return Err(LocalizeError::RoiShape {
            side,
            len,
            max: MAX_SIDE,
        });
    }
    Ok(())
}

/// What to do with hot pixels (paper §4, Fig. 8: ignoring them was better).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum HotPixelMode {
    /// Leave hot pixels out of the likelihood.
    #[default]
    Ignore,
    /// Replace each by the mean of its valid 4-neighbours and fit it as data.
    Interpolate,
}

/// Applies a hot-pixel strategy to one ROI: `hot` marks hot pixels. With
/// [`HotPixelMode::Ignore`] they are added to `maps.ignore`; with
/// [`HotPixelMode::Interpolate`] their data are replaced by the mean of the
/// valid 4-neighbours (not hot, not ignored, inside the ROI). A hot pixel with
/// no valid neighbour is ignored instead; the number of those is returned.
pub fn apply_hot_pixels(
    data: &mut [f64],
    hot: &[bool],
    mode: HotPixelMode,
    maps: &mut PixelMaps,
) -> Result<usize, LocalizeError> {
    let side = maps.side;
    check_shape(side, data.len())?;
    if hot.len() != data.len() {
        return Err(LocalizeError::MapShape {
            map: "hot-pixel",
            len: hot.len(),
            expected: data.len(),
        });
    }
    let mut fallback = 0;
    match mode {
        HotPixelMode::Ignore => {
            for (ig, &h) in maps.ignore.iter_mut().zip(hot) {
                *ig |= h;
            }
        }
        HotPixelMode::Interpolate => {
            // Read neighbours from the original data so that the result does not
            // depend on the order in which hot pixels are visited.
            let original = data.to_vec();
            for k in 0..data.len() {
                if !hot[k] {
                    continue;
                }
                let (i, j) = ((k % side) as isize, (k / side) as isize);
                let mut sum = 0.0;
                let mut n = 0;
                for (di, dj) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
                    let (a, b) = (i + di, j + dj);
                    if a < 0 || b < 0 || a >= side as isize || b >= side as isize {
                        continue;
                    }
                    let q = b as usize * side + a as usize;
                    if !hot[q] && !maps.ignore[q] {
                        sum += original[q];
                        n += 1;
                    }
                }
                if n > 0 {
                    data[k] = sum / n as f64;
                } else {
                    maps.ignore[k] = true;
                    fallback += 1;
                }
            }
        }
    }
    Ok(fallback)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_uses_valid_neighbours_only() {
        let side = 3;
        let mut data = vec![1.0, 2.0, 3.0, 4.0, 100.0, 6.0, 7.0, 8.0, 9.0];
        let mut hot = vec![false; 9];
        hot[4] = true; // centre
        hot[1] = true; // its upper neighbour is hot too
        let mut maps = PixelMaps::uniform(side);
        maps.ignore[5] = true; // right neighbour off the sensor
        let fb = apply_hot_pixels(&mut data, &hot, HotPixelMode::Interpolate, &mut maps).unwrap();
        assert_eq!(fb, 0);
        // Centre: neighbours 4 (left) and 8 (below) are valid.
        assert_eq!(data[4], (4.0 + 8.0) / 2.0);
        // Top middle: neighbours 1 (left) and 3 (right) valid, centre hot.
        assert_eq!(data[1], 2.0);
        let mut maps = PixelMaps::uniform(side);
        let mut d2 = vec![0.0; 9];
        apply_hot_pixels(&mut d2, &hot, HotPixelMode::Ignore, &mut maps).unwrap();
        assert_eq!(maps.ignored(), 2);
        assert!(apply_hot_pixels(&mut d2, &hot[..4], HotPixelMode::Ignore, &mut maps).is_err());
    }

    #[test]
    fn bad_maps_are_named() {
        let mut m = PixelMaps::uniform(3);
        m.gain[2] = 0.0;
        assert!(m.validate().unwrap_err().to_string().contains("gain"));
        let mut m = PixelMaps::uniform(3);
        m.dark.pop();
        assert!(m.validate().unwrap_err().to_string().contains("dark"));
        assert!(RoiView::new(3, &[0.0; 8], None).is_err());
        assert!(RoiView::new(65, &vec![0.0; 65 * 65], None).is_err());
    }
}
