//! One module per `smartagg` command: each has `Args` (clap) and `run`.

pub mod aggregate;
pub mod bench_aggregate;
pub mod bench_drift;
pub mod bench_false_blinks;
pub mod bench_frames;
pub mod bench_localize;
pub mod bench_simulate;
pub mod calibrate;
pub mod cosim;
pub mod demo;
pub mod download;
pub mod drift;
pub mod hdl;
pub mod inspect;
pub mod localize;
pub mod params;
pub mod presets;
pub mod render;
pub mod simulate;
pub mod study;
