//! Per-pixel maps of a SPAD sensor: the one type every crate reads them in.
//!
//! The scene simulator draws them (`smartagg_scene::spad`), a calibration
//! measures them (`smartagg_calibration::Calibration::sensor_maps`), the
//! study crops a calibrated sensor's maps to its field, and the record fits
//! cut them to a blink's ROI (`smartagg_localize::record_fit`). A pixel's
//! detection efficiency is the camera's η = PDE × fill factor times the
//! pixel's relative response (PRNU), clamped to a probability
//! ([`SensorMaps::efficiency`]); its expected dark counts in one bit-plane
//! are its dark-count rate times the plane's duration.

use thiserror::Error;

/// Dark-count rates, relative responses and hot pixels of a
/// `width × height` SPAD sensor, raster order (pixel `(x, y)` at
/// `y · width + x`).
///
/// The fields are public so that tests and simulators can shape a sensor;
/// [`SensorMaps::validate`] checks what a consumer relies on.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorMaps {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Dark-count rate, Hz (finite, ≥ 0), `width · height` values.
    pub dcr_hz: Vec<f64>,
    /// Relative photon response (PRNU: 1 is the camera's η, 0 a dead
    /// pixel; finite, ≥ 0), if known; without it every pixel responds as
    /// the camera's η.
    pub prnu: Option<Vec<f64>>,
    /// Whether the pixel is hot (by whatever criterion made the maps).
    pub hot: Vec<bool>,
}

/// Why [`SensorMaps::validate`] or [`SensorMaps::crop`] refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SensorMapsError {
    /// A map's length is not `width · height`.
    #[error("the {map} map has {len} values for {width}x{height} pixels")]
    Shape {
        /// Which map: "DCR", "PRNU" or "hot-pixel".
        map: &'static str,
        /// Its length.
        len: usize,
        /// Sensor width, pixels.
        width: u32,
        /// Sensor height, pixels.
        height: u32,
    },
    /// A value that is not a finite number ≥ 0.
    #[error("the {map} of pixel ({x}, {y}) is {value}, not a finite number ≥ 0")]
    Value {
        /// Which map: "DCR" or "PRNU".
        map: &'static str,
        /// Column.
        x: u32,
        /// Row.
        y: u32,
        /// The value.
        value: f64,
    },
    /// The sensor has no pixel.
    #[error("the sensor has no pixels ({width}x{height})")]
    Empty {
        /// Width, pixels.
        width: u32,
        /// Height, pixels.
        height: u32,
    },
    /// A crop reaches past the sensor.
    #[error("a {w}x{h} crop at ({x0}, {y0}) leaves the {width}x{height} sensor")]
    Crop {
        /// Crop origin, column.
        x0: u32,
        /// Crop origin, row.
        y0: u32,
        /// Crop width.
        w: u32,
        /// Crop height.
        h: u32,
        /// Sensor width.
        width: u32,
        /// Sensor height.
        height: u32,
    },
}

impl SensorMaps {
    /// A sensor of `width × height` pixels with the dark-count rate
    /// `dcr_hz` everywhere, the camera's η everywhere (no PRNU map) and no
    /// hot pixel.
    pub fn uniform(width: u32, height: u32, dcr_hz: f64) -> SensorMaps {
        let n = width as usize * height as usize;
        SensorMaps {
            width,
            height,
            dcr_hz: vec![dcr_hz; n],
            prnu: None,
            hot: vec![false; n],
        }
    }

    /// Number of pixels, `width · height`.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Raster index of pixel `(x, y)`, `None` off the sensor.
    pub fn index(&self, x: u32, y: u32) -> Option<usize> {
        (x < self.width && y < self.height).then(|| y as usize * self.width as usize + x as usize)
    }

    /// Checks the map sizes and values; the error names the first bad one.
    pub fn validate(&self) -> Result<(), SensorMapsError> {
        let n = self.pixels();
        if n == 0 {
            return Err(SensorMapsError::Empty {
                width: self.width,
                height: self.height,
            });
        }
        let shape = |map, len| SensorMapsError::Shape {
            map,
            len,
            width: self.width,
            height: self.height,
        };
        if self.dcr_hz.len() != n {
            return Err(shape("DCR", self.dcr_hz.len()));
        }
        if let Some(p) = self.prnu.as_ref().filter(|p| p.len() != n) {
            return Err(shape("PRNU", p.len()));
        }
        if self.hot.len() != n {
            return Err(shape("hot-pixel", self.hot.len()));
        }
        let bad = |map, values: &[f64]| {
            values
                .iter()
                .position(|v| !(v.is_finite() && *v >= 0.0))
                .map(|i| SensorMapsError::Value {
                    map,
                    x: (i % self.width as usize) as u32,
                    y: (i / self.width as usize) as u32,
                    value: values[i],
                })
        };
        if let Some(e) = bad("DCR", &self.dcr_hz) {
            return Err(e);
        }
        if let Some(e) = self.prnu.as_deref().and_then(|p| bad("PRNU", p)) {
            return Err(e);
        }
        Ok(())
    }

    /// Relative response of raster pixel `i` (1 without a PRNU map).
    pub fn prnu_of(&self, i: usize) -> f64 {
        self.prnu.as_ref().map_or(1.0, |p| p[i])
    }

    /// Detection efficiency of every pixel for a camera of efficiency
    /// `eta` (PDE × fill factor): `eta · PRNU`, clamped to [0, 1].
    pub fn efficiency(&self, eta: f64) -> Vec<f64> {
        (0..self.pixels())
            .map(|i| (eta * self.prnu_of(i)).clamp(0.0, 1.0))
            .collect()
    }

    /// Expected dark counts of raster pixel `i` in one bit-plane of
    /// `plane_period_s` seconds.
    pub fn dark_per_plane(&self, i: usize, plane_period_s: f64) -> f64 {
        self.dcr_hz[i] * plane_period_s
    }

    /// Number of hot pixels.
    pub fn hot_pixels(&self) -> usize {
        self.hot.iter().filter(|&&h| h).count()
    }

    /// The maps of the `w × h` window at `(x0, y0)`, hot pixels included.
    pub fn crop(&self, x0: u32, y0: u32, w: u32, h: u32) -> Result<SensorMaps, SensorMapsError> {
        let fits = |o: u32, s: u32, total: u32| o.checked_add(s).is_some_and(|e| e <= total);
        if !fits(x0, w, self.width) || !fits(y0, h, self.height) {
            return Err(SensorMapsError::Crop {
                x0,
                y0,
                w,
                h,
                width: self.width,
                height: self.height,
            });
        }
        let width = self.width as usize;
        let idx: Vec<usize> = (y0 as usize..(y0 + h) as usize)
            .flat_map(|y| {
                let start = y * width + x0 as usize;
                start..start + w as usize
            })
            .collect();
        Ok(SensorMaps {
            width: w,
            height: h,
            dcr_hz: idx.iter().map(|&i| self.dcr_hz[i]).collect(),
            prnu: self
                .prnu
                .as_ref()
                .map(|p| idx.iter().map(|&i| p[i]).collect()),
            hot: idx.iter().map(|&i| self.hot[i]).collect(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: u32, h: u32) -> SensorMaps {
        let n = (w * h) as usize;
        SensorMaps {
            width: w,
            height: h,
            dcr_hz: (0..n).map(|i| i as f64).collect(),
            prnu: Some(
                (0..n)
                    .map(|i| if i % 2 == 0 { 0.5 } else { 30.0 })
                    .collect(),
            ),
            hot: (0..n).map(|i| i % 7 == 3).collect(),
        }
    }

    #[test]
    fn a_crop_takes_the_pixels_at_its_offset() {
        let m = ramp(20, 10);
        m.validate().unwrap();
        let c = m.crop(3, 5, 4, 2).unwrap();
        assert_eq!((c.width, c.height, c.dcr_hz.len()), (4, 2, 8));
        // Crop (1, 1) is sensor (4, 6): raster 6·20 + 4 = 124.
        assert_eq!(c.dcr_hz[4 + 1], 124.0);
        assert_eq!(c.prnu_of(4 + 1), 0.5);
        assert_eq!(c.hot[4 + 1], 124 % 7 == 3);
        assert_eq!(c.hot_pixels(), c.hot.iter().filter(|&&h| h).count());
        c.validate().unwrap();
        assert_eq!(m.crop(0, 0, 20, 10).unwrap(), m);
    }

    #[test]
    fn a_crop_past_the_edge_is_refused() {
        let m = ramp(20, 10);
        assert!(m.crop(17, 0, 4, 1).is_err());
        assert!(m.crop(0, 9, 1, 2).is_err());
        assert!(m.crop(u32::MAX, 0, 2, 1).is_err(), "no overflow");
        assert!(m.crop(16, 8, 4, 2).is_ok());
    }

    #[test]
    fn efficiency_is_prnu_times_eta_and_stays_a_probability() {
        let m = ramp(4, 2);
        let e = m.efficiency(0.1);
        assert_eq!(e[0], 0.1 * 0.5);
        assert_eq!(e[1], 1.0, "30 × 0.1 is clamped");
        assert!(SensorMaps::uniform(4, 2, 5.0)
            .efficiency(0.3)
            .iter()
            .all(|&x| x == 0.3));
        assert_eq!(m.dark_per_plane(5, 1e-4), 5.0 * 1e-4);
    }

    #[test]
    fn bad_maps_are_named() {
        let mut m = ramp(4, 4);
        m.dcr_hz[5] = f64::NAN;
        let e = m.validate().unwrap_err().to_string();
        assert!(e.contains("DCR of pixel (1, 1)"), "{e}");
        let mut m = ramp(4, 4);
        m.prnu = Some(vec![1.0; 3]);
        assert!(m
            .validate()
            .unwrap_err()
            .to_string()
            .contains("PRNU map has 3"));
        let mut m = ramp(4, 4);
        m.prnu.as_mut().unwrap()[15] = -1.0;
        assert!(m.validate().unwrap_err().to_string().contains("(3, 3)"));
        let mut m = ramp(4, 4);
        m.hot.pop();
        assert!(m.validate().unwrap_err().to_string().contains("hot-pixel"));
        assert!(SensorMaps::uniform(0, 4, 1.0).validate().is_err());
        assert!(SensorMaps::uniform(4, 4, 1.0).validate().is_ok());
        assert_eq!(m.index(4, 0), None);
        assert_eq!(ramp(4, 4).index(3, 2), Some(11));
    }
}
