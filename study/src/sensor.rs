//! A calibrated sensor in the study (`smartagg study … --calibration DIR`):
//! instead of the preset's synthetic dark-count, hot-pixel and PRNU maps,
//! the SPCImager configurations simulate the maps that `smartagg calibrate`
//! measured on a real camera, so the study predicts what *that* sensor does.
//!
//! * Every work item simulates a `field × field` crop of the calibrated
//!   sensor at an offset drawn from the item's seed (so the items sample the
//!   whole sensor, and shards still merge bit-identically).
//! * Dark counts: the calibrated DCR of each pixel (hot ones included, at
//!   their measured rate). Detection efficiency: the preset's PDE × fill
//!   factor × the calibrated PRNU (1 without a flat), clamped to [0, 1].
//! * Hot pixels are those whose dark counts alone would reach this
//!   configuration's hold level (the calibration's criterion re-derived for
//!   its N and T_hold, the paper's Eq. 7 threshold: a hot pixel there would
//!   keep a neighbouring track on); the smart pipeline masks them as
//!   `smartagg aggregate --calibration` does, the localisers leave them out
//!   of the likelihood, and the fixed-frame `hot` curves use the same set.
//!
//! The maps themselves are not stored in the study's manifest (only
//! [`SensorCalibration::id`], which names the folder and the CRC of its maps),
//! so shards run with different calibrations refuse to merge.

use serde::{Deserialize, Serialize};
use smartagg_calibration::{Calibration, CalibrationError, HotCriterion};
use smartagg_model::params::SpadCamera;
use smartagg_scene::spad::SpadMaps;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The critical dark-count rate of a configuration: `(N, T)` → the DCR at
/// and above which a pixel's dark counts alone reach T (`None`: no rate
/// can), or why it cannot be derived. The study asks it at the pipeline's
/// hold level T_hold. [`SensorCalibration::load`] makes it from the
/// calibration's [`HotCriterion`] ([`SensorMaps::critical_dcr_of`]); tests
/// put their own rule in its place.
pub type CriticalDcr = dyn Fn(u32, u64) -> Result<Option<f64>, String> + Send + Sync;

/// Calibrated per-pixel maps of a whole sensor, raster order.
pub struct SensorMaps {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Dark-count rate, Hz (finite, ≥ 0).
    pub dcr_hz: Vec<f64>,
    /// Relative photon detection efficiency (mean 1), if a flat was recorded.
    pub prnu: Option<Vec<f64>>,
    /// The hot-pixel criterion of the calibration, for any N and threshold.
    pub critical_dcr: Box<CriticalDcr>,
}

impl std::fmt::Debug for SensorMaps {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SensorMaps")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("prnu", &self.prnu.is_some())
            .finish_non_exhaustive()
    }
}

impl SensorMaps {
    /// The [`CriticalDcr`] of a calibration's hot-pixel criterion: the
    /// criterion re-derived for `(N, T)`, its critical rate.
    pub fn critical_dcr_of(criterion: HotCriterion) -> Box<CriticalDcr> {
        Box::new(move |n, t| {
            criterion
                .with_threshold(n, t)
                .map(|c| c.dcr_critical_hz)
                .map_err(|e| e.to_string())
        })
    }

    /// Checks the map sizes and values; the error names the first bad one.
    pub fn validate(&self) -> Result<(), String> {
        let n = self.width as usize * self.height as usize;
        if n == 0 {
            return Err("the calibrated sensor has no pixels".into());
        }
        if self.dcr_hz.len() != n {
            return Err(format!(
                "the DCR map has {} values for {}x{} pixels",
                self.dcr_hz.len(),
                self.width,
                self.height
            ));
        }
        if let Some(i) = self
            .dcr_hz
            .iter()
            .position(|d| !(d.is_finite() && *d >= 0.0))
        {
            return Err(format!(
                "the DCR of pixel ({}, {}) is {}, not a finite rate ≥ 0",
                i % self.width as usize,
                i / self.width as usize,
                self.dcr_hz[i]
            ));
        }
        if let Some(p) = &self.prnu {
            if p.len() != n {
                return Err(format!(
                    "the PRNU map has {} values for {n} pixels",
                    p.len()
                ));
            }
            if let Some(i) = p.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(format!(
                    "the PRNU of pixel ({}, {}) is {}, not a finite factor ≥ 0",
                    i % self.width as usize,
                    i / self.width as usize,
                    p[i]
                ));
            }
        }
        Ok(())
    }

    /// The simulator's maps of the `field × field` crop at `(x0, y0)` for a
    /// camera, with pixels hot at and above `critical_dcr_hz`.
    pub fn crop(
        &self,
        camera: &SpadCamera,
        field: u32,
        (x0, y0): (u32, u32),
        critical_dcr_hz: Option<f64>,
    ) -> SpadMaps {
        let n = field as usize * field as usize;
        let mut maps = SpadMaps {
            width: field,
            height: field,
            eta: Vec::with_capacity(n),
            dcr_hz: Vec::with_capacity(n),
            hot: Vec::with_capacity(n),
        };
        for y in 0..field {
            for x in 0..field {
                let i = (y0 + y) as usize * self.width as usize + (x0 + x) as usize;
                let d = self.dcr_hz[i];
                let prnu = self.prnu.as_ref().map_or(1.0, |p| p[i]);
                maps.eta.push((camera.eta() * prnu).clamp(0.0, 1.0));
                maps.dcr_hz.push(d);
                maps.hot.push(critical_dcr_hz.is_some_and(|c| d >= c));
            }
        }
        maps
    }

    /// The crop offset of a work item: uniform over the sensor from `seed`.
    pub fn offset(&self, field: u32, seed: u64) -> (u32, u32) {
        let span_x = u64::from(self.width - field) + 1;
        let span_y = u64::from(self.height - field) + 1;
        let s = crate::timeline::derive_seed(&[seed, 0xC41B_0FF5]);
        ((s % span_x) as u32, ((s >> 32) % span_y) as u32)
    }

    /// PRNU of pixel `(x, y)` (1 without a flat).
    pub fn prnu_at(&self, x: u32, y: u32) -> f64 {
        self.prnu
            .as_ref()
            .map_or(1.0, |p| p[y as usize * self.width as usize + x as usize])
    }
}

/// A calibrated sensor as a study option: the identity is what the manifest
/// records and what shards compare; the maps come from the command line.
#[derive(Clone, Serialize, Deserialize)]
pub struct SensorCalibration {
    /// Where the maps came from (folder and CRC of the maps).
    pub id: String,
    /// The maps (absent when the options were read back from a manifest).
    #[serde(skip)]
    pub maps: Option<Arc<SensorMaps>>,
}

/// Why [`SensorCalibration::load`] failed.
#[derive(Debug, thiserror::Error)]
pub enum SensorLoadError {
    /// The calibration folder could not be read.
    #[error("loading calibration {}", path.display())]
    Load {
        /// The folder.
        path: PathBuf,
        /// Why.
        #[source]
        source: CalibrationError,
    },
    /// The calibration's maps are not a usable sensor
    /// ([`SensorMaps::validate`]).
    #[error("calibration {}: {why}", path.display())]
    Invalid {
        /// The folder.
        path: PathBuf,
        /// The first bad map or value.
        why: String,
    },
}

impl SensorCalibration {
    /// The calibrated sensor of `study --calibration DIR`: the SPAD
    /// calibration folder's maps, its hot-pixel criterion (re-derived for
    /// any N and T_int) and the identity that the manifest records — the
    /// folder, size, dark planes and a CRC-32C of the maps (DCR, then PRNU),
    /// so that shards run on different calibrations refuse to merge.
    pub fn load(path: &Path) -> Result<SensorCalibration, SensorLoadError> {
        let cal = Calibration::load(path).map_err(|source| SensorLoadError::Load {
            path: path.to_path_buf(),
            source,
        })?;
        let mut bytes = Vec::with_capacity(cal.dcr_hz.len() * 16);
        for d in &cal.dcr_hz {
            bytes.extend_from_slice(&d.to_le_bytes());
        }
        for p in cal.prnu.iter().flatten() {
            bytes.extend_from_slice(&p.to_le_bytes());
        }
        let id = format!(
            "{} ({}x{} px, {} dark planes, maps CRC-32C {:08x})",
            path.display(),
            cal.width,
            cal.height,
            cal.planes,
            smartagg_model::packet::crc32c(&bytes)
        );
        let maps = SensorMaps {
            width: cal.width,
            height: cal.height,
            dcr_hz: cal.dcr_hz,
            prnu: cal.prnu,
            critical_dcr: SensorMaps::critical_dcr_of(cal.hot_criterion),
        };
        maps.validate().map_err(|why| SensorLoadError::Invalid {
            path: path.to_path_buf(),
            why,
        })?;
        Ok(SensorCalibration {
            id,
            maps: Some(Arc::new(maps)),
        })
    }
}

impl PartialEq for SensorCalibration {
    fn eq(&self, other: &Self) -> bool {
        self.id == other.id
    }
}

impl std::fmt::Debug for SensorCalibration {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SensorCalibration")
            .field("id", &self.id)
            .field("maps", &self.maps)
            .finish()
    }
}

/// A calibrated sensor applied to one configuration: the maps and the
/// critical DCR under its N and T_hold.
#[derive(Debug, Clone)]
pub struct CalibratedSetup {
    /// The sensor's maps.
    pub maps: Arc<SensorMaps>,
    /// DCR at and above which a pixel is hot for this configuration.
    pub critical_dcr_hz: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use smartagg_model::params::{Camera, Preset, PresetName};

    fn maps(w: u32, h: u32) -> SensorMaps {
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
            critical_dcr: Box::new(|_, _| Ok(Some(100.0))),
        }
    }

    #[test]
    fn a_crop_takes_the_sensors_pixels_at_its_offset() {
        let Camera::Spad(cam) = Preset::new(PresetName::Spcimager, 150).unwrap().camera else {
            panic!("SPCImager is a SPAD")
        };
        let m = maps(20, 10);
        m.validate().unwrap();
        let c = m.crop(&cam, 4, (3, 5), Some(120.0));
        assert_eq!(c.dcr_hz.len(), 16);
        // Pixel (1, 2) of the crop is (4, 7) of the sensor: raster 7·20 + 4.
        assert_eq!(c.dcr_hz[2 * 4 + 1], 144.0);
        assert!(c.hot[2 * 4 + 1], "144 Hz ≥ 120 Hz is hot");
        assert!(!c.hot[0], "(3, 5) of the sensor reads 103 Hz < 120 Hz");
    }

    #[test]
    fn efficiency_is_prnu_times_the_cameras_and_stays_a_probability() {
        let Camera::Spad(cam) = Preset::new(PresetName::Spcimager, 150).unwrap().camera else {
            panic!("SPCImager is a SPAD")
        };
        let m = maps(8, 8);
        let c = m.crop(&cam, 8, (0, 0), None);
        assert!((c.eta[0] - 0.5 * cam.eta()).abs() < 1e-12);
        assert!(c.eta.iter().all(|&e| (0.0..=1.0).contains(&e)));
        assert_eq!(c.eta[1], (30.0 * cam.eta()).min(1.0));
        assert!(c.hot.iter().all(|&h| !h), "no criterion, no hot pixel");
    }

    #[test]
    fn offsets_cover_the_sensor_and_stay_inside() {
        let m = maps(40, 30);
        let mut seen_x = std::collections::BTreeSet::new();
        for seed in 0..2000 {
            let (x, y) = m.offset(16, seed);
            assert!(x <= 24 && y <= 14);
            seen_x.insert(x);
        }
        assert_eq!(seen_x.len(), 25, "every x offset occurs");
        assert_eq!(maps(16, 16).offset(16, 5), (0, 0));
    }

    #[test]
    fn bad_maps_are_named() {
        let mut m = maps(4, 4);
        m.dcr_hz[5] = f64::NAN;
        assert!(m.validate().unwrap_err().contains("(1, 1)"));
        let mut m = maps(4, 4);
        m.prnu = Some(vec![1.0; 3]);
        assert!(m.validate().unwrap_err().contains("PRNU map has 3"));
    }
}
