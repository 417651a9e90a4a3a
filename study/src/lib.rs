//! # smartagg-study — the paper's simulation study, and beyond
//!
//! Reproduces the projections of the paper (the simulated curves of Fig. 4
//! and the four panels of Fig. 8) on top of the scene simulator
//! (`smartagg-scene`), the real smart-aggregation pipeline and packet path
//! (`smartagg-model`) and the localisers (`smartagg-localize`), so that a
//! user can rerun them with their own camera and optics. `smartagg study`
//! is the command line; everything is callable from here.
//!
//! ## Studies ([`spec::StudyName`])
//!
//! | study | curves |
//! |---|---|
//! | `smart-vs-fixed` | SPCIMAGER 150x: fixed 500-plane frames, smart (Poisson MLE), smart (SPAD binomial MLE), smart with the paper's literal scheme (one threshold, `L_min = 1`), Cramér–Rao bound |
//! | `future-spad` | current and projected SPAD (3x fill, DCR/4): fixed, smart, smart SPAD MLE, bound |
//! | `cameras` | projected SPAD smart vs EMCCD and sCMOS 50 ms frames, each merged (40 nm) or not |
//! | `objective` | smart aggregation at 150x and 60x, current and projected SPAD |
//! | `hot-pixels` | 50 ms frames with the molecule on throughout, 0-20 % hot pixels ignored or interpolated, 150x and 60x |
//! | `localizers` | centroid, LSQ, MLE (σ fixed/fitted), SPAD MLE (σ fixed/fitted) on the same smart ROIs: RMSE, bias, RMSE/CRLB, fits/s |
//!
//! The paper's experiment in simulation ([`experiment`], one job each):
//! `nanoruler` (EMCCD vs SPCIMAGER fixed/smart behind a 50/50 splitter,
//! Figs. 6–7), `emccd-frames` (Fig. 4 right), `blink-durations` (Fig. 5,
//! the estimator's bias and why blinks give several records) and
//! `detection` (Eq. 5's 99 % against the exact statistics; error against N).
//!
//! ## How a point is computed
//!
//! A point (a blink duration, or a hot-pixel fraction) is split into work
//! items of [`spec::StudyOptions::block`] blinks ([`item`]). Each item draws
//! its blinks from a seed derived from (seed, point, block) ([`timeline`]):
//! one molecule at a time, every blink of the point's duration, at a random
//! relative position. Every configuration (camera, objective) of the study
//! simulates **the same blinks** as one continuous recording ([`acquisition`]):
//! SPAD bit-planes go through the model's pipeline (the field design; fast
//! engine, byte-identical to the golden one) and then through the packetiser and
//! the packet decoder; fixed frames are sums of 500 of the same bit-planes;
//! EMCCD and sCMOS frames come from their simulators. ROIs and frames are
//! localised ([`frames`], the localize crate's frame pipeline and merging)
//! and matched to the truth ([`matching`]: within 53.3 nm and overlapping
//! in time). [`stats`] turns the per-blink outcomes into RMS errors,
//! detection and false-positive rates and paired bootstrap intervals;
//! [`report`] writes `points.csv`, `ratios.csv`, `timing.csv`, a PNG and
//! `summary.md`, whose last section ([`notes`]) explains where and why the
//! results differ from the paper.
//!
//! ## Sharding ([`run`], [`store`])
//!
//! Items run in parallel on all cores (rayon). `--shard I/N` runs the items
//! whose canonical index is `I − 1 mod N` and writes their raw per-blink
//! results; `smartagg study merge` checks that the shards belong to one
//! study and cover every item once, and writes exactly the files one run
//! would have written (bit-identical: results depend only on the seeds, and
//! numbers round-trip through the CSV files exactly).
//!
//! ## Decisions
//!
//! * **Smart aggregation is the field design** (`model::field_design`), on
//!   each configuration's study field, as `smartagg aggregate` defaults to
//!   ([`acquisition::field_design_config`]): an open threshold T_open that keeps
//!   background within 1 false blink/s over the field, the paper's Eq. 7
//!   threshold as the hold level, r_assoc = round(2σ), L_min = 1, and each
//!   blink summed to its estimated end (`end_trim = ⌊N/2⌋`). The paper's
//!   literal scheme (one threshold, L_min 1, r_assoc 1, end_trim 0; measured:
//!   ~500 false blinks/s through a 32x32 field, and those near the molecule
//!   add poor localisations, [`notes`]) is a curve of `smart-vs-fixed`
//!   ([`acquisition::paper_config`]). `--l-min` and `--r-assoc` override the field
//!   design's L_min and r_assoc, never the paper's scheme. The `detection`
//!   study's part A measures the paper's Eq. 5/7 threshold itself.
//! * Frames are localised with ThunderSTORM's defaults (wavelet filter,
//!   1.5 × robust std of F1, 9×9 Poisson MLE, σ fitted by default).
//! * The Cramér–Rao reference is the SPAD binomial bound of an ideal
//!   aggregation of exactly the blink's on-planes, at its true position.
//! * Smart records whose planes and ROI cannot reach any blink are false
//!   positives whatever their fit and are not fitted (most false blinks);
//!   every other record and every frame candidate is fitted.
//! * Wall times are reported beside every result but kept out of
//!   `points.csv`, so that merged shards are bit-identical to one run.

#![warn(missing_docs)]

pub mod acquisition;
pub mod error;
pub mod experiment;
pub mod frames;
pub mod item;
pub mod matching;
pub mod notes;
pub mod report;
pub mod run;
pub mod sensor;
pub mod spec;
pub mod stats;
pub mod store;
pub mod timeline;

pub use error::StudyError;
pub use spec::{Plan, Shard, StudyName, StudyOptions};
