//! # smartagg-scene — blinking molecules seen by SPAD, EMCCD and sCMOS cameras
//!
//! The simulation model of section 4 and Table 1 of the paper, used to predict
//! what a camera will do before it is built and to test every other part of
//! smartagg. Everything is reproducible from one `u64` seed.
//!
//! * [`scene`]: the field (ROI), optics, light levels, emitter layout
//!   (random, GATTA-PAINT 80G nanorulers, a user list) and blinking (one
//!   molecule at a time as in the study, independent on/off kinetics at SMLM
//!   density, or an explicit list of blinks);
//! * [`psf`]: the Gaussian PSF (σ = r/3) integrated exactly over each pixel;
//! * [`spad`]: the binary SPAD camera, one [`BitPlane`](smartagg_model::plane::BitPlane)
//!   per call, exact pile-up, PRNU, DRNU and hot pixels, fast enough for
//!   the SPCImager's own 10,000 planes/s;
//! * [`frames`]: the EMCCD and sCMOS cameras, one frame of ADU per call
//!   (`smartagg_io::stack::StackWriter` writes them as a TIFF stack);
//! * [`drift`]: stage drift, a smooth trajectory added to every position;
//! * [`truth`]: the ground truth, one row per blink, and its CSV file;
//!
//! ## Coordinates and time
//!
//! Positions are in nm in the sample plane, relative to the top-left corner of
//! the simulated field: pixel `(i, j)` covers `[i·p, (i+1)·p) × [j·p, (j+1)·p)`
//! with `p` the pixel size in the sample plane, so its centre is at
//! `((i + ½)·p, (j + ½)·p)`. Time is in seconds from the start of the first
//! bit-plane or frame; plane (frame) `k` exposes `[k·period, k·period + exposure)`.
//!
//! ## Random streams
//!
//! One seed drives five independent ChaCha8 streams: 0 camera maps (PRNU,
//! DRNU, hot pixels, sCMOS offsets…), 1 emitter layout, 2 blinking, 3 photon
//! and noise sampling, 4 a random stage drift. The blink timeline therefore depends only on the scene
//! and the seed, not on the camera: the same seed gives the same molecules to
//! a SPAD and an EMCCD simulation of the same field in nm.

pub mod bench;
pub mod drift;
pub mod frames;
pub mod psf;
pub mod scene;
pub mod spad;
pub mod truth;

mod emission;
mod sampling;
mod timeline;

pub use drift::DriftTrajectory;
pub use frames::{EmccdSimulator, Frame, ScmosMaps, ScmosNonUniformity, ScmosSimulator};
pub use scene::{Blinking, ExplicitBlink, Layout, OnTime, Position, Scene};
pub use spad::{generate_maps, uniform_maps, SpadSimulator};
pub use truth::BlinkTruth;

use smartagg_model::params::ParamError;
use smartagg_model::recording::RecordingError;
use smartagg_model::sensor_maps::SensorMapsError;
use thiserror::Error;

/// Anything that stops a simulation from being set up or written.
#[derive(Debug, Error)]
pub enum SceneError {
    /// A camera, optics, light or scene parameter outside its physical range
    /// (the message names it).
    #[error(transparent)]
    Param(#[from] ParamError),
    /// The simulated field (ROI) does not fit on the sensor.
    #[error("invalid parameter `{name}` = {value} px: the simulated field (ROI) is larger than the sensor ({sensor} px)")]
    RoiTooLarge {
        /// `width` or `height`.
        name: &'static str,
        /// The requested field size.
        value: u32,
        /// The sensor's size along that axis.
        sensor: u32,
    },
    /// Per-pixel maps of the wrong size for the field.
    #[error("per-pixel maps are {found} pixels, the field has {expected}")]
    MapSize {
        /// Pixels in the field.
        expected: usize,
        /// Pixels in the maps.
        found: usize,
    },
    /// A SPAD sensor's maps of another size than the field.
    #[error("the sensor maps are {}x{} pixels, the field is {}x{}", maps.0, maps.1, field.0, field.1)]
    MapShape {
        /// Width and height of the maps.
        maps: (u32, u32),
        /// Width and height of the field.
        field: (u32, u32),
    },
    /// A SPAD sensor's maps that are not a sensor (the first bad map or value).
    #[error(transparent)]
    Maps(#[from] SensorMapsError),
    /// A ground-truth CSV file that cannot be parsed.
    #[error("ground-truth CSV line {line}: {why}")]
    TruthCsv {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        why: String,
    },
    /// Reading or writing a file failed.
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
    /// The bit-plane container refused something.
    #[error(transparent)]
    Recording(#[from] RecordingError),
}
