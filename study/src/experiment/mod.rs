//! The paper's experiment (§4.1, Figs. 4 right, 5, 6, 7) and the detection
//! statistics of §3, in simulation: `nanoruler`, `emccd-frames`,
//! `blink-durations` and `detection`. Each writes a CSV of every point, a
//! PNG and a Markdown summary like the other studies, but runs as one job
//! (no shards): these are single recordings or small sweeps.

pub mod blink_durations;
pub mod common;
pub mod detection;
pub mod emccd_frames;
pub mod field_detection;
pub mod nanoruler;
pub mod notes;

use crate::error::StudyError;
use std::path::{Path, PathBuf};

/// The experiment studies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Experiment {
    /// Nanorulers imaged by the SPCIMAGER and an EMCCD behind a splitter.
    Nanoruler,
    /// EMCCD error against blink duration, merged or not (Fig. 4 right).
    EmccdFrames,
    /// Estimated blink durations against the truth (Fig. 5).
    BlinkDurations,
    /// Detection and false-alarm probabilities against N and T; error against N.
    Detection,
    /// Detection on the whole sensor: false blinks, recall, records per blink.
    FieldDetection,
}

impl Experiment {
    /// Every experiment study.
    pub const ALL: [Experiment; 5] = [
        Experiment::Nanoruler,
        Experiment::EmccdFrames,
        Experiment::BlinkDurations,
        Experiment::Detection,
        Experiment::FieldDetection,
    ];

    /// Command-line name.
    pub fn as_str(self) -> &'static str {
        match self {
            Experiment::Nanoruler => "nanoruler",
            Experiment::EmccdFrames => "emccd-frames",
            Experiment::BlinkDurations => "blink-durations",
            Experiment::Detection => "detection",
            Experiment::FieldDetection => "field-detection",
        }
    }

    /// The study called `s`, if it is an experiment study.
    pub fn parse(s: &str) -> Option<Experiment> {
        Experiment::ALL.into_iter().find(|e| e.as_str() == s)
    }
}

/// Options shared by the experiment studies.
#[derive(Debug, Clone, Copy)]
pub struct ExperimentOptions {
    /// Master seed.
    pub seed: u64,
    /// Smaller run (tests).
    pub quick: bool,
    /// Blinks per point (studies with points), default when `None`.
    pub blinks_per_point: Option<u32>,
}

/// Runs `exp` and writes its outputs to `out`; returns the files written
/// and warnings (a plot that could not be drawn).
pub fn run(
    exp: Experiment,
    o: &ExperimentOptions,
    out: &Path,
) -> Result<(Vec<PathBuf>, Vec<String>), StudyError> {
    match exp {
        Experiment::Nanoruler => {
            let r = nanoruler::compute(&nanoruler::NanorulerOptions::new(o.seed, o.quick))?;
            nanoruler::write(out, &r)
        }
        Experiment::EmccdFrames => {
            let r = emccd_frames::compute(o.seed, o.quick, o.blinks_per_point)?;
            emccd_frames::write(out, &r)
        }
        Experiment::BlinkDurations => {
            let r = blink_durations::compute(o.seed, o.quick, o.blinks_per_point)?;
            blink_durations::write(out, &r)
        }
        Experiment::Detection => {
            let r = detection::compute(o.seed, o.quick, o.blinks_per_point)?;
            detection::write(out, &r)
        }
        Experiment::FieldDetection => {
            let r = field_detection::compute(o.seed, o.quick, o.blinks_per_point)?;
            field_detection::write(out, &r)
        }
    }
}
