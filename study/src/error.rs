//! Everything that can stop a study, each with a message naming what is wrong.

use std::path::PathBuf;
use thiserror::Error;

/// Why a study could not be run, merged or written.
#[derive(Debug, Error)]
pub enum StudyError {
    /// A study name that is not one of [`crate::StudyName::ALL`].
    #[error("unknown study `{0}`: expected one of smart-vs-fixed, future-spad, cameras, objective, hot-pixels, localizers, nanoruler, emccd-frames, blink-durations, detection")]
    UnknownStudy(String),
    /// An option outside its range.
    #[error("invalid option `{name}`: {why}")]
    Option {
        /// The option.
        name: &'static str,
        /// What is wrong with it.
        why: String,
    },
    /// A `--shard` value that is not `I/N` with `1 ≤ I ≤ N`.
    #[error("invalid shard `{0}`: expected I/N with 1 <= I <= N (e.g. 3/8)")]
    Shard(String),
    /// A camera, optics or light parameter.
    #[error(transparent)]
    Param(#[from] smartagg_model::params::ParamError),
    /// The detection statistics (window N, threshold T).
    #[error(transparent)]
    Stats(#[from] smartagg_model::stats::StatsError),
    /// The pipeline refused its configuration or a plane.
    #[error(transparent)]
    Pipeline(#[from] smartagg_model::pipeline::PipelineError),
    /// The pipeline configuration is invalid.
    #[error(transparent)]
    Config(#[from] smartagg_model::config::ConfigError),
    /// The packet encoder refused a record.
    #[error(transparent)]
    Packet(#[from] smartagg_model::packet::PacketError),
    /// Decoding the study's own packet stream lost data (a bug, never silent).
    #[error("the packet stream of a simulated recording lost data: {0}")]
    PacketLoss(String),
    /// The scene simulator refused the scene.
    #[error(transparent)]
    Scene(#[from] smartagg_scene::SceneError),
    /// The localiser refused an ROI or its maps.
    #[error(transparent)]
    Localize(#[from] smartagg_localize::LocalizeError),
    /// Reading or writing a file.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What failed.
        source: std::io::Error,
    },
    /// A study output file that cannot be read back.
    #[error("{path} line {line}: {why}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number (0 for the whole file).
        line: usize,
        /// What is wrong.
        why: String,
    },
    /// Shard outputs that do not belong together or leave gaps.
    #[error("cannot merge shards: {0}")]
    Merge(String),
    /// A plot that could not be drawn.
    #[error("plot {path}: {why}")]
    Plot {
        /// The PNG file.
        path: PathBuf,
        /// What failed.
        why: String,
    },
}

impl StudyError {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> StudyError {
        StudyError::Io {
            path: path.into(),
            source,
        }
    }
}
