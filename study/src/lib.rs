//! # smartagg-study — the paper's simulation study, and beyond
//!
//! Reproduces the projections of the paper (Fig. 4 simulated curves and the
//! four panels of Fig. 8) on top of the scene simulator, the real
//! smart-aggregation pipeline and packet path, and the localisers.
pub mod error;
pub mod frames;
pub mod item;
pub mod matching;
pub mod notes;
pub mod report;
pub mod run;
pub mod sim;
pub mod spec;
pub mod stats;
pub mod store;
pub mod timeline;

pub use error::StudyError;
pub use spec::{Plan, Shard, StudyName, StudyOptions};
