//! Where the experiment studies differ from the paper, and why (filled in
//! from measured runs).

/// Notes of the `nanoruler` study.
pub const NANORULER: &str = "(to be written from the measured runs)";

/// Notes of the `emccd-frames` study.
pub const EMCCD_FRAMES: &str = "(to be written from the measured runs)";

/// Notes of the `blink-durations` study.
pub const BLINK_DURATIONS: &str = "(to be written from the measured runs)";

/// Notes of the `detection` study.
pub const DETECTION: &str = "(to be written from the measured runs)";
