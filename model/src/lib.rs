//! # smartagg-model — the golden, bit-accurate model
//!
//! This crate is the reference for everything else in smartagg: the gateware
//! in `hdl/` must produce exactly the bytes that [`pipeline::Pipeline`]
//! produces, and the host decodes exactly what [`packet`] defines.
//!
//! * [`params`]: cameras, optics and the presets of Table 1 of the paper;
//!   [`sensor_maps`]: a SPAD sensor's per-pixel dark-count rates, PRNU and
//!   hot pixels, simulated or calibrated;
//! * [`kernel`], [`stats`], [`false_alarm`]: the paper's Eq. 1–7 with the
//!   integer kernel actually used, the window N, the threshold T and T_int,
//!   and the predicted false-alarm rate and confirmation length L_min;
//! * [`field_design`]: the detection design for a whole sensor (open and
//!   hold thresholds for a false-blink budget, association radius) and the
//!   recall it predicts;
//! * the streaming pipeline, one stage per file with the same names as in
//!   `hdl/`: [`hot_pixel_mask`], [`delay_line`], [`rolling_count`],
//!   [`spatial_filter`], [`threshold`], [`candidates`], [`blink_tracker`],
//!   [`roi_aggregator`], [`packetiser`], wired together by [`pipeline`];
//! * [`fast_engine`]: the same records from incremental stages 1–4, on
//!   several cores;
//! * [`record`] and [`packet`]: the records and their byte format;
//! * [`recording`]: the `.spad` bit-plane container and raw packed planes.

pub mod back_end;
pub mod blink_tracker;
pub mod candidates;
pub mod config;
pub mod delay_line;
pub mod false_alarm;
pub mod fast_engine;
pub mod field_design;
pub mod hot_pixel_mask;
pub mod kernel;
pub mod packet;
pub mod packetiser;
pub mod params;
pub mod pipeline;
pub mod plane;
pub mod record;
pub mod record_check;
pub mod recording;
pub mod registers;
pub mod rice;
pub mod roi_aggregator;
pub mod rolling_count;
pub mod sensor_maps;
pub mod spatial_filter;
pub mod stats;
pub mod threshold;
