//! What the camera looks at: the field, the optics, the light and the
//! molecules with their blinking.
//!
//! ## Defaults
//!
//! * [`Scene::study`] — the paper's simulation study (§4): a square field of
//!   the preset's `study_field_px` (32×32 SPAD, 16×16 EMCCD, 40×40 sCMOS),
//!   one molecule on at a time at a random position at least 3σ from the
//!   field's edge, every blink lasting exactly the swept duration, separated by
//!   10 ms plus an exponential gap of mean 40 ms.
//! * [`Scene::smlm`] — a realistic dSTORM field over the whole sensor:
//!   50 emitters/µm² placed uniformly at random, each switching independently
//!   with exponential on-times of mean 30 ms and off-times of mean 30 s (duty
//!   cycle ≈ 1/1000, typical of dSTORM dyes). At 150× the SPCImager field is
//!   17.1 × 12.8 µm = 218 µm², ≈ 10,900 emitters of which ≈ 11 are on at
//!   any time; at 60× the field is 6.25× larger and ≈ 68 are on.
//! * [`Scene::nanorulers`] — GATTA-PAINT 80G nanorulers over the whole
//!   sensor: 0.5 rulers/µm², three markers 80 nm apart on a line of random
//!   orientation, exponential on-times of mean 30 ms and off-times of mean 3 s
//!   (≈ 3 markers on at a time at 150×).
//!
//! Molecules do not bleach. Blink intensities vary with a Gamma-distributed
//! factor of mean 1 and relative spread [`Scene::intensity_cv`] (0 = every
//! blink has exactly the light's flux).

use smartagg_model::params::{
    check_non_negative, check_positive, check_range, Camera, Optics, ParamError, Preset, SceneLight,
};

use crate::SceneError;

/// A position in the sample plane, nm from the field's top-left corner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Position {
    /// Horizontal, nm (increasing to the right).
    pub x_nm: f64,
    /// Vertical, nm (increasing downwards).
    pub y_nm: f64,
}

/// Where the emitters are.
#[derive(Debug, Clone, PartialEq)]
pub enum Layout {
    /// A Poisson number of emitters of mean `density_per_um2` × field area,
    /// uniform in the field (less [`Scene::margin_px`]). With
    /// [`Blinking::OneAtATime`] every blink is at a fresh uniform position
    /// instead and the density is not used.
    Random {
        /// Emitters per µm² of sample.
        density_per_um2: f64,
    },
    /// Nanorulers: a Poisson number of rulers of mean `rulers_per_um2` × area,
    /// centres uniform in the field (less the margin), orientation uniform;
    /// `markers` emitters `spacing_nm` apart on a line through the centre.
    Nanorulers {
        /// Rulers per µm².
        rulers_per_um2: f64,
        /// Distance between neighbouring markers, nm (80 for GATTA-PAINT 80G).
        spacing_nm: f64,
        /// Markers per ruler (3 for GATTA-PAINT 80G).
        markers: u32,
    },
    /// The user's emitters.
    List(Vec<Position>),
}

impl Layout {
    /// GATTA-PAINT 80G rulers (three markers, 80 nm apart) at the given density.
    pub fn gatta_paint_80g(rulers_per_um2: f64) -> Layout {
        Layout::Nanorulers {
            rulers_per_um2,
            spacing_nm: 80.0,
            markers: 3,
        }
    }
}

/// How long a blink lasts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OnTime {
    /// Every blink lasts exactly this long, s (the study sweeps it).
    Fixed {
        /// Blink duration, s.
        seconds: f64,
    },
    /// Exponentially distributed blink durations.
    Exponential {
        /// Mean blink duration, s.
        mean_s: f64,
    },
}

impl OnTime {
    /// Mean blink duration, s.
    pub fn mean_s(&self) -> f64 {
        match *self {
            OnTime::Fixed { seconds } => seconds,
            OnTime::Exponential { mean_s } => mean_s,
        }
    }
}

/// One blink given explicitly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExplicitBlink {
    /// Emitter identifier reported in the ground truth.
    pub emitter: u64,
    /// Where the emitter is.
    pub position: Position,
    /// Start of the blink, s (may be negative: on before the recording starts).
    pub t_on_s: f64,
    /// End of the blink, s (≥ `t_on_s`).
    pub t_off_s: f64,
    /// Multiplies the light's molecule flux for this blink (1 = nominal).
    pub flux_factor: f64,
}

/// When the molecules are on.
#[derive(Debug, Clone, PartialEq)]
pub enum Blinking {
    /// One molecule on at a time (the paper's study): a blink of duration
    /// `on`, then nothing for `gap_min_s` + Exp(`gap_mean_s`), then the next
    /// blink, at a new position (see [`Layout`]). The first blink starts after
    /// such a gap.
    OneAtATime {
        /// Blink duration.
        on: OnTime,
        /// Smallest dark gap between blinks, s.
        gap_min_s: f64,
        /// Mean of the exponential part of the gap, s.
        gap_mean_s: f64,
    },
    /// Every emitter of the layout switches independently: on for `on`, off
    /// for Exp(`mean_off_s`). At t = 0 each emitter is in its stationary state
    /// (on with probability mean_on / (mean_on + mean_off), part-way through).
    Independent {
        /// Blink duration.
        on: OnTime,
        /// Mean off (dark) time, s.
        mean_off_s: f64,
    },
    /// Exactly these blinks (the layout is not used).
    Explicit(Vec<ExplicitBlink>),
}

/// A complete scene: field, optics, light, emitters and blinking.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Width of the simulated field (ROI), pixels.
    pub width: u32,
    /// Height of the simulated field (ROI), pixels.
    pub height: u32,
    /// Objective and emission.
    pub optics: Optics,
    /// Molecule flux and background.
    pub light: SceneLight,
    /// Emitter positions.
    pub layout: Layout,
    /// On/off behaviour.
    pub blinking: Blinking,
    /// Relative spread of the per-blink intensity (0 = none).
    pub intensity_cv: f64,
    /// Random positions keep at least this far from the field's edge, pixels.
    pub margin_px: f64,
}

impl Scene {
    /// The paper's study scene for `preset` with blinks of `blink_s` seconds.
    pub fn study(preset: &Preset, blink_s: f64) -> Scene {
        let f = preset.study_field_px;
        Scene {
            width: f,
            height: f,
            optics: preset.optics,
            light: preset.light,
            layout: Layout::Random {
                density_per_um2: 0.0,
            },
            blinking: Blinking::OneAtATime {
                on: OnTime::Fixed { seconds: blink_s },
                gap_min_s: 0.010,
                gap_mean_s: 0.040,
            },
            intensity_cv: 0.0,
            margin_px: (3.0 * preset.sigma_px()).min(f as f64 / 4.0),
        }
    }

    /// A realistic dSTORM field over the whole sensor (see the module docs).
    pub fn smlm(preset: &Preset) -> Scene {
        let (w, h) = preset.camera.size();
        Scene {
            width: w,
            height: h,
            optics: preset.optics,
            light: preset.light,
            layout: Layout::Random {
                density_per_um2: 50.0,
            },
            blinking: Blinking::Independent {
                on: OnTime::Exponential { mean_s: 0.030 },
                mean_off_s: 30.0,
            },
            intensity_cv: 0.0,
            margin_px: 0.0,
        }
    }

    /// GATTA-PAINT 80G nanorulers over the whole sensor (see the module docs).
    pub fn nanorulers(preset: &Preset) -> Scene {
        Scene {
            layout: Layout::gatta_paint_80g(0.5),
            blinking: Blinking::Independent {
                on: OnTime::Exponential { mean_s: 0.030 },
                mean_off_s: 3.0,
            },
            ..Scene::smlm(preset)
        }
    }

    /// The same scene on a field of `width × height` pixels.
    pub fn with_field(mut self, width: u32, height: u32) -> Scene {
        self.width = width;
        self.height = height;
        self
    }

    /// Pixel size in the sample plane for `camera`, nm.
    pub fn pixel_nm(&self, camera: &Camera) -> f64 {
        self.optics.pixel_nm(camera.pixel_pitch_um())
    }

    /// PSF σ in pixels of `camera`.
    pub fn sigma_px(&self, camera: &Camera) -> f64 {
        self.optics.psf_sigma_px(camera.pixel_pitch_um())
    }

    /// Expected number of emitters on at a time (independent kinetics), or
    /// at most 1 (one at a time), or `None` for explicit blinks.
    pub fn expected_on(&self, camera: &Camera) -> Option<f64> {
        let p = self.pixel_nm(camera) / 1000.0;
        let area = self.width as f64 * p * self.height as f64 * p;
        let emitters = match &self.layout {
            Layout::Random { density_per_um2 } => density_per_um2 * area,
            Layout::Nanorulers {
                rulers_per_um2,
                markers,
                ..
            } => rulers_per_um2 * area * *markers as f64,
            Layout::List(v) => v.len() as f64,
        };
        match &self.blinking {
            Blinking::OneAtATime {
                on,
                gap_min_s,
                gap_mean_s,
            } => Some(on.mean_s() / (on.mean_s() + gap_min_s + gap_mean_s)),
            Blinking::Independent { on, mean_off_s } => {
                Some(emitters * on.mean_s() / (on.mean_s() + mean_off_s))
            }
            Blinking::Explicit(_) => None,
        }
    }

    /// Checks the scene against `camera`; the error names the first bad parameter.
    pub fn validate(&self, camera: &Camera) -> Result<(), SceneError> {
        camera.validate()?;
        self.optics.validate()?;
        self.light.validate()?;
        let (sw, sh) = camera.size();
        for (name, value, sensor) in [("width", self.width, sw), ("height", self.height, sh)] {
            if value == 0 {
                return Err(ParamError::Invalid {
                    name,
                    value: 0.0,
                    why: "the simulated field (ROI) must be at least 1 pixel",
                }
                .into());
            }
            if value > sensor {
                return Err(SceneError::RoiTooLarge {
                    name,
                    value,
                    sensor,
                });
            }
        }
        check_range("intensity_cv", self.intensity_cv, 0.0, 10.0)?;
        check_non_negative("margin_px", self.margin_px)?;
        if 2.0 * self.margin_px >= self.width.min(self.height) as f64 {
            return Err(ParamError::Invalid {
                name: "margin_px",
                value: self.margin_px,
                why: "the margins leave no room in the field for emitters",
            }
            .into());
        }
        match &self.layout {
            Layout::Random { density_per_um2 } => {
                check_range("density_per_um2", *density_per_um2, 0.0, 1e5)?;
            }
            Layout::Nanorulers {
                rulers_per_um2,
                spacing_nm,
                markers,
            } => {
                check_range("rulers_per_um2", *rulers_per_um2, 0.0, 1e4)?;
                check_non_negative("spacing_nm", *spacing_nm)?;
                check_range("markers", *markers as f64, 1.0, 1000.0)?;
            }
            Layout::List(v) => {
                for p in v {
                    check_finite("x_nm", p.x_nm)?;
                    check_finite("y_nm", p.y_nm)?;
                }
            }
        }
        let check_on = |on: &OnTime| -> Result<(), ParamError> {
            match *on {
                OnTime::Fixed { seconds } => {
                    check_positive("blink duration (s)", seconds).map(|_| ())
                }
                OnTime::Exponential { mean_s } => {
                    check_positive("mean on time (s)", mean_s).map(|_| ())
                }
            }
        };
        match &self.blinking {
            Blinking::OneAtATime {
                on,
                gap_min_s,
                gap_mean_s,
            } => {
                check_on(on)?;
                check_non_negative("gap_min_s", *gap_min_s)?;
                check_non_negative("gap_mean_s", *gap_mean_s)?;
                if let Layout::List(v) = &self.layout {
                    if v.is_empty() {
                        return Err(ParamError::Invalid {
                            name: "layout",
                            value: 0.0,
                            why: "one-at-a-time blinking of a user list needs at least one emitter",
                        }
                        .into());
                    }
                }
            }
            Blinking::Independent { on, mean_off_s } => {
                check_on(on)?;
                check_positive("mean_off_s", *mean_off_s)?;
            }
            Blinking::Explicit(v) => {
                for b in v {
                    check_finite("x_nm", b.position.x_nm)?;
                    check_finite("y_nm", b.position.y_nm)?;
                    check_finite("t_on_s", b.t_on_s)?;
                    check_finite("t_off_s", b.t_off_s)?;
                    if b.t_off_s < b.t_on_s {
                        return Err(ParamError::Invalid {
                            name: "t_off_s",
                            value: b.t_off_s,
                            why: "a blink cannot end before it starts",
                        }
                        .into());
                    }
                    check_non_negative("flux_factor", b.flux_factor)?;
                }
            }
        }
        Ok(())
    }
}

fn check_finite(name: &'static str, v: f64) -> Result<f64, ParamError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ParamError::Invalid {
            name,
            value: v,
            why: "must be a finite number",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use smartagg_model::params::PresetName;

    #[test]
    fn defaults_are_valid_and_realistic() {
        let p = Preset::new(PresetName::Spcimager, 150).unwrap();
        for s in [
            Scene::study(&p, 0.03),
            Scene::smlm(&p),
            Scene::nanorulers(&p),
        ] {
            s.validate(&p.camera).unwrap();
        }
        let on = Scene::smlm(&p).expected_on(&p.camera).unwrap();
        assert!((on - 10.9).abs() < 0.3, "{on}");
        let p60 = Preset::new(PresetName::Spcimager, 60).unwrap();
        let on60 = Scene::smlm(&p60).expected_on(&p60.camera).unwrap();
        assert!((on60 / on - 6.25).abs() < 0.01);
    }

    #[test]
    fn roi_larger_than_sensor_is_named() {
        let p = Preset::new(PresetName::Spcimager, 150).unwrap();
        let e = Scene::smlm(&p)
            .with_field(321, 10)
            .validate(&p.camera)
            .unwrap_err();
        assert!(e.to_string().contains("`width` = 321"), "{e}");
        let e = Scene::smlm(&p)
            .with_field(10, 241)
            .validate(&p.camera)
            .unwrap_err();
        assert!(e.to_string().contains("`height`"), "{e}");
    }
}
