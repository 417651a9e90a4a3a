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
use smartagg_model::sensor_maps::{SensorMaps, SensorMapsError};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The critical dark-count rate of a configuration: `(N, T)` → the DCR at
/// and above which a pixel's dark counts alone reach T (`None`: no rate
/// can), or why it cannot be derived. The study asks it at the pipeline's
/// hold level T_hold. [`SensorCalibration::load`] makes it from the
/// calibration's [`HotCriterion`] ([`CalibratedSensor::critical_dcr_of`]); tests
/// put their own rule in its place.
pub type CriticalDcr = dyn Fn(u32, u64) -> Result<Option<f64>, String> + Send + Sync;

/// A calibrated sensor: its maps (the calibration's `HOT` flags as hot
/// pixels) and its hot-pixel criterion for any N and threshold.
pub struct CalibratedSensor {
    /// The whole sensor's maps, raster order.
    pub maps: SensorMaps,
    /// The hot-pixel criterion of the calibration, for any N and threshold.
    pub critical_dcr: Box<CriticalDcr>,
}

impl std::fmt::Debug for CalibratedSensor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CalibratedSensor")
            .field("width", &self.maps.width)
            .field("height", &self.maps.height)
            .field("prnu", &self.maps.prnu.is_some())
            .finish_non_exhaustive()
    }
}

impl CalibratedSensor {
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

    /// The simulator's maps of the `field × field` crop at `(x0, y0)`, with
    /// the pixels hot at and above `critical_dcr_hz` (none without one).
    pub fn crop(
        &self,
        field: u32,
        (x0, y0): (u32, u32),
        critical_dcr_hz: Option<f64>,
    ) -> Result<SensorMaps, SensorMapsError> {
        let mut maps = self.maps.crop(x0, y0, field, field)?;
        for (hot, &d) in maps.hot.iter_mut().zip(&maps.dcr_hz) {
            *hot = critical_dcr_hz.is_some_and(|c| d >= c);
        }
        Ok(maps)
    }

    /// The crop offset of a work item: uniform over the sensor from `seed`.
    pub fn offset(&self, field: u32, seed: u64) -> (u32, u32) {
        let span_x = u64::from(self.maps.width - field) + 1;
        let span_y = u64::from(self.maps.height - field) + 1;
        let s = crate::timeline::derive_seed(&[seed, 0xC41B_0FF5]);
        ((s % span_x) as u32, ((s >> 32) % span_y) as u32)
    }
}

/// A calibrated sensor as a study option: the identity is what the manifest
/// records and what shards compare; the maps come from the command line.
#[derive(Clone, Serialize, Deserialize)]
pub struct SensorCalibration {
    /// Where the maps came from (folder and CRC of the maps).
    pub id: String,
    /// The sensor (absent when the options were read back from a manifest).
    #[serde(skip)]
    pub sensor: Option<Arc<CalibratedSensor>>,
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
        // `Calibration::load` has checked the maps' sizes and values; the
        // study checks them again where any sensor enters (`with_sensor`).
        let sensor = CalibratedSensor {
            maps: cal.sensor_maps(),
            critical_dcr: CalibratedSensor::critical_dcr_of(cal.hot_criterion),
        };
        Ok(SensorCalibration {
            id,
            sensor: Some(Arc::new(sensor)),
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
            .field("sensor", &self.sensor)
            .finish()
    }
}

/// A calibrated sensor applied to one configuration: the sensor and the
/// critical DCR under its N and T_hold.
#[derive(Debug, Clone)]
pub struct CalibratedSetup {
    /// The sensor.
    pub sensor: Arc<CalibratedSensor>,
    /// DCR at and above which a pixel is hot for this configuration.
    pub critical_dcr_hz: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sensor(w: u32, h: u32) -> CalibratedSensor {
        let n = (w * h) as usize;
        CalibratedSensor {
            maps: SensorMaps {
                width: w,
                height: h,
                dcr_hz: (0..n).map(|i| i as f64).collect(),
                prnu: None,
                // Every pixel flagged: the crop judges them by its own rate.
                hot: vec![true; n],
            },
            critical_dcr: Box::new(|_, _| Ok(Some(100.0))),
        }
    }

    #[test]
    fn a_crop_takes_the_sensors_pixels_at_its_offset_and_its_hot_pixels_from_the_rate() {
        let m = sensor(20, 10);
        m.maps.validate().unwrap();
        let c = m.crop(4, (3, 5), Some(120.0)).unwrap();
        assert_eq!(c.dcr_hz.len(), 16);
        // Pixel (1, 2) of the crop is (4, 7) of the sensor: raster 7·20 + 4.
        assert_eq!(c.dcr_hz[2 * 4 + 1], 144.0);
        assert!(c.hot[2 * 4 + 1], "144 Hz ≥ 120 Hz is hot");
        assert!(!c.hot[0], "(3, 5) of the sensor reads 103 Hz < 120 Hz");
        let none = m.crop(8, (0, 0), None).unwrap();
        assert!(none.hot.iter().all(|&h| !h), "no criterion, no hot pixel");
        assert!(
            m.crop(16, (0, 0), None).is_err(),
            "16 rows on a 10-row sensor"
        );
    }

    #[test]
    fn offsets_cover_the_sensor_and_stay_inside() {
        let m = sensor(40, 30);
        let mut seen_x = std::collections::BTreeSet::new();
        for seed in 0..2000 {
            let (x, y) = m.offset(16, seed);
            assert!(x <= 24 && y <= 14);
            seen_x.insert(x);
        }
        assert_eq!(seen_x.len(), 25, "every x offset occurs");
        assert_eq!(sensor(16, 16).offset(16, 5), (0, 0));
    }
}
