//! What a blink record can and cannot contain, given its stream's
//! StreamStart: a CRC-valid record that breaks one of these rules did not
//! come from a pipeline that ran the stream's configuration (a corrupted
//! capture that happened to pass the CRC, or a stream put together by hand),
//! and a consumer must not fit it.
//!
//! The rules follow from the pipeline (model/PACKETS.md):
//! - the anchor is a pixel of the sensor, the slot one of the stream's slots
//!   and the ROI side the stream's R, with R×R counts;
//! - `t_drop ≥ t_cross`, except for a continuation cut on the stream's
//!   last plane (CONTINUATION | TRUNCATED, `t_drop = t_cross − 1`);
//! - `planes_summed` is the length of the range [`summed_planes`] gives:
//!   `[max(0, t_cross − N), t_drop − end_trim]` after a drop, `t_drop − N`
//!   as the end after a cut, `t_drop` when truncated (version 3); a
//!   version-1 or 2 stream summed `[max(0, t_cross − N), t_drop]`, a
//!   continuation from `t_cross` (PACKETS.md §8.6);
//! - a bit-plane adds at most one detection per pixel, so no count exceeds
//!   `planes_summed`, and a stream of `P` planes holds no plane at or after `P`.

use crate::record::{flags, BlinkRecord, StreamStart};

/// Why a blink record cannot be what the stream says it is.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Implausible {
    /// The stream's sensor has no pixels.
    #[error("the stream's sensor is {0}x{1} pixels")]
    EmptySensor(u16, u16),
    /// The anchor lies off the sensor.
    #[error("anchor ({x}, {y}) is off the {width}x{height} sensor")]
    AnchorOffSensor {
        /// Anchor column.
        x: u16,
        /// Anchor row.
        y: u16,
        /// Sensor width.
        width: u16,
        /// Sensor height.
        height: u16,
    },
    /// The slot is not one of the stream's slots.
    #[error("slot {slot} of a stream with {slots} slots")]
    SlotOutOfRange {
        /// The record's slot.
        slot: u8,
        /// The stream's slot count.
        slots: u8,
    },
    /// The ROI is not the stream's R×R.
    #[error("a {side}x{side} ROI with {counts} counts in a stream of {roi}x{roi} ROIs")]
    RoiShape {
        /// The record's ROI side.
        side: u8,
        /// Number of counts it carries.
        counts: usize,
        /// The stream's ROI side.
        roi: u8,
    },
    /// `t_drop < t_cross` outside an empty continuation.
    #[error("t_drop {t_drop} before t_cross {t_cross}")]
    EndsBeforeItStarts {
        /// Plane the track opened.
        t_cross: u64,
        /// Last plane summed.
        t_drop: u64,
    },
    /// Planes summed disagree with the segment's planes.
    #[error("{planes_summed} planes summed for planes {t_cross}..={t_drop}")]
    PlanesSummed {
        /// The record's count.
        planes_summed: u32,
        /// Plane the track opened.
        t_cross: u64,
        /// Last plane summed.
        t_drop: u64,
    },
    /// A pixel counted more detections than planes were summed.
    #[error("a pixel counts {count} detections in {planes_summed} planes")]
    CountAbovePlanes {
        /// The largest count.
        count: u32,
        /// Planes summed.
        planes_summed: u32,
    },
    /// The segment ends at or after the stream's last plane.
    #[error("plane {t_drop} of a stream of {planes} planes")]
    AfterStreamEnd {
        /// Last plane summed.
        t_drop: u64,
        /// Planes in the stream (its StreamEnd).
        planes: u64,
    },
}

/// Finds packets that repeat an earlier one of the same stream file: a
/// Blink, Dropped or Overflow record with the same sequence number and the
/// same content (a duplicated transfer, a capture concatenated with itself),
/// compared by a 64-bit hash of the record.
/// StreamStart and StreamEnd are never repeats: two captures of one
/// configuration legitimately share them. Holds 16 bytes per packet seen.
#[derive(Debug, Default)]
pub struct RepeatFilter {
    seen: std::collections::HashSet<(u32, u64)>,
    repeats: u64,
}

impl RepeatFilter {
    /// Whether the packet `(seq, record)` repeats one seen before; counts it.
    pub fn is_repeat(&mut self, seq: u32, record: &crate::record::Record) -> bool {
        use crate::record::Record;
        use std::hash::{Hash, Hasher};
        if matches!(record, Record::Start(_) | Record::End(_)) {
            return false;
        }
        let mut h = std::collections::hash_map::DefaultHasher::new();
        record.hash(&mut h);
        let repeat = !self.seen.insert((seq, h.finish()));
        self.repeats += u64::from(repeat);
        repeat
    }

    /// Repeats found so far.
    pub fn repeats(&self) -> u64 {
        self.repeats
    }
}

/// Whether `r` is an empty segment, which sums no plane (nothing to fit):
/// in version 3 a first segment cut or dropped before its first plane came
/// out of the window; in versions 1 and 2 a continuation cut on its last
/// plane.
pub fn is_empty_segment(r: &BlinkRecord) -> bool {
    r.planes_summed == 0
}

/// The bit-planes that `r` summed, as the half-open range `first..end`
/// (`end == first` when it summed none), by the rule of its stream's
/// version (PACKETS.md §8.6). Saturates on values no pipeline writes;
/// [`check_blink`] tells those apart.
pub fn summed_planes(r: &BlinkRecord, start: &StreamStart) -> std::ops::Range<u64> {
    summed_planes_by(r, start.n_window, start.end_trim)
}

/// [`summed_planes`] from the stream's window N and `end_trim` (`None`: a
/// version-1 or 2 stream).
pub fn summed_planes_by(
    r: &BlinkRecord,
    n_window: u32,
    end_trim: Option<u32>,
) -> std::ops::Range<u64> {
    let n = u64::from(n_window);
    let continuation = r.has(flags::CONTINUATION);
    let first = match end_trim {
        None if continuation => r.t_cross,
        _ => r.t_cross.saturating_sub(n),
    };
    let after = r.t_drop.saturating_add(1);
    let end = match end_trim {
        None => after,
        Some(_) if r.has(flags::CUT) => after.saturating_sub(n),
        Some(_) if r.has(flags::TRUNCATED) => after,
        Some(c) => after.saturating_sub(u64::from(c)),
    };
    first..end.max(first)
}

/// Checks `r` against its stream's `start` and, when known, the stream's
/// plane count (from its StreamEnd).
pub fn check_blink(
    r: &BlinkRecord,
    start: &StreamStart,
    planes: Option<u64>,
) -> Result<(), Implausible> {
    if start.width == 0 || start.height == 0 {
        return Err(Implausible::EmptySensor(start.width, start.height));
    }
    if r.anchor_x >= start.width || r.anchor_y >= start.height {
        return Err(Implausible::AnchorOffSensor {
            x: r.anchor_x,
            y: r.anchor_y,
            width: start.width,
            height: start.height,
        });
    }
    if r.slot >= start.slots {
        return Err(Implausible::SlotOutOfRange {
            slot: r.slot,
            slots: start.slots,
        });
    }
    let side = r.roi_size as usize;
    if r.roi_size != start.roi_size || r.counts.len() != side * side {
        return Err(Implausible::RoiShape {
            side: r.roi_size,
            counts: r.counts.len(),
            roi: start.roi_size,
        });
    }
    let earliest_drop = if r.has(flags::CONTINUATION) {
        r.t_cross.saturating_sub(1)
    } else {
        r.t_cross
    };
    if r.t_drop < earliest_drop {
        return Err(Implausible::EndsBeforeItStarts {
            t_cross: r.t_cross,
            t_drop: r.t_drop,
        });
    }
    let summed = summed_planes(r, start);
    if u64::from(r.planes_summed) != summed.end - summed.start {
        return Err(Implausible::PlanesSummed {
            planes_summed: r.planes_summed,
            t_cross: r.t_cross,
            t_drop: r.t_drop,
        });
    }
    if let Some(&c) = r.counts.iter().max() {
        if c > r.planes_summed {
            return Err(Implausible::CountAbovePlanes {
                count: c,
                planes_summed: r.planes_summed,
            });
        }
    }
    if let Some(p) = planes {
        if r.t_drop >= p {
            return Err(Implausible::AfterStreamEnd {
                t_drop: r.t_drop,
                planes: p,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::PipelineConfig;

    fn start() -> StreamStart {
        let mut c = PipelineConfig::new(16, 12, 10, vec![1, 2, 1], 2, 20);
        c.roi_size = 3;
        c.slots = 4;
        c.stream_start()
    }

    fn blink() -> BlinkRecord {
        BlinkRecord {
            slot: 1,
            flags: 0,
            anchor_x: 5,
            anchor_y: 6,
            t_cross: 40,
            t_drop: 59,
            t_s: 35,
            t_e: 54,
            planes_summed: 30,
            roi_size: 3,
            counts: vec![1, 2, 3, 4, 30, 4, 3, 2, 1],
        }
    }

    #[test]
    fn repeats_are_blinks_seen_before_never_starts_or_ends() {
        use crate::record::{Record, StreamEnd};
        let mut f = RepeatFilter::default();
        let end = Record::End(StreamEnd::default());
        let b = Record::Blink(blink());
        assert!(!f.is_repeat(0, &Record::Start(start())));
        assert!(!f.is_repeat(1, &b));
        assert!(!f.is_repeat(2, &end));
        assert!(!f.is_repeat(0, &Record::Start(start())));
        assert!(f.is_repeat(1, &b));
        assert!(!f.is_repeat(2, &end));
        // Same content under another sequence number is another packet.
        assert!(!f.is_repeat(7, &b));
        assert_eq!(f.repeats(), 1);
    }

    #[test]
    fn a_pipeline_like_record_passes() {
        assert_eq!(check_blink(&blink(), &start(), Some(100)), Ok(()));
        // Pre-roll clipped at plane 0.
        let b = BlinkRecord {
            t_cross: 4,
            t_drop: 9,
            planes_summed: 10,
            counts: vec![0; 9],
            ..blink()
        };
        assert_eq!(check_blink(&b, &start(), None), Ok(()));
        // Version 3: a continuation also sums from t_cross − N; cut ends
        // N planes early, a drop end_trim planes early, a truncation at t_drop.
        let c = BlinkRecord {
            flags: flags::CONTINUATION,
            counts: vec![0; 9],
            ..blink()
        };
        assert_eq!(check_blink(&c, &start(), Some(60)), Ok(()));
        let cut = BlinkRecord {
            flags: flags::CUT,
            planes_summed: 20,
            counts: vec![0; 9],
            ..blink()
        };
        assert_eq!(check_blink(&cut, &start(), None), Ok(()));
        assert_eq!(summed_planes(&cut, &start()), 30..50);
        let mut trimmed = start();
        trimmed.end_trim = Some(5);
        let d = BlinkRecord {
            planes_summed: 25,
            counts: vec![0; 9],
            ..blink()
        };
        assert_eq!(check_blink(&d, &trimmed, None), Ok(()));
        assert!(check_blink(&blink(), &trimmed, None).is_err());
        let tr = BlinkRecord {
            flags: flags::TRUNCATED,
            ..blink()
        };
        assert_eq!(check_blink(&tr, &trimmed, Some(60)), Ok(()));
        // The continuation of a cut on the last plane sums the last N planes.
        let last = BlinkRecord {
            flags: flags::CONTINUATION | flags::TRUNCATED,
            t_drop: 39,
            planes_summed: 10,
            counts: vec![0; 9],
            ..blink()
        };
        assert_eq!(check_blink(&last, &start(), Some(40)), Ok(()));
        // A first segment that ends before its first plane left the window
        // summed nothing.
        let e3 = BlinkRecord {
            t_cross: 0,
            t_drop: 3,
            planes_summed: 0,
            counts: vec![0; 9],
            ..blink()
        };
        assert!(is_empty_segment(&e3));
        assert_eq!(check_blink(&e3, &trimmed, None), Ok(()));
        assert!(check_blink(&e3, &start(), None).is_err());

        // Version 2: a continuation sums from t_cross; a cut on the last
        // plane leaves an empty one.
        let mut v2 = start();
        v2.end_trim = None;
        let c = BlinkRecord {
            flags: flags::CONTINUATION,
            planes_summed: 20,
            counts: vec![0; 9],
            ..blink()
        };
        assert_eq!(check_blink(&c, &v2, Some(60)), Ok(()));
        assert!(check_blink(&c, &start(), Some(60)).is_err());
        let cut2 = BlinkRecord {
            flags: flags::CUT,
            ..blink()
        };
        assert_eq!(check_blink(&cut2, &v2, None), Ok(()));
        let e = BlinkRecord {
            flags: flags::CONTINUATION | flags::TRUNCATED,
            t_drop: 39,
            planes_summed: 0,
            counts: vec![0; 9],
            ..blink()
        };
        assert!(is_empty_segment(&e));
        assert_eq!(check_blink(&e, &v2, Some(40)), Ok(()));
    }

    #[test]
    fn each_impossible_record_is_named() {
        let s = start();
        let cases: Vec<(BlinkRecord, &str)> = vec![
            (
                BlinkRecord {
                    anchor_x: 16,
                    ..blink()
                },
                "off the 16x12 sensor",
            ),
            (
                BlinkRecord { slot: 4, ..blink() },
                "slot 4 of a stream with 4 slots",
            ),
            (
                BlinkRecord {
                    roi_size: 5,
                    counts: vec![0; 25],
                    ..blink()
                },
                "5x5 ROI",
            ),
            (
                BlinkRecord {
                    counts: vec![0; 4],
                    ..blink()
                },
                "4 counts",
            ),
            (
                BlinkRecord {
                    t_drop: 39,
                    ..blink()
                },
                "before t_cross",
            ),
            (
                BlinkRecord {
                    planes_summed: 0,
                    ..blink()
                },
                "0 planes summed",
            ),
            (
                BlinkRecord {
                    planes_summed: 31,
                    ..blink()
                },
                "31 planes summed",
            ),
            (
                BlinkRecord {
                    counts: vec![31; 9],
                    ..blink()
                },
                "31 detections in 30 planes",
            ),
        ];
        for (b, want) in cases {
            let e = check_blink(&b, &s, None).unwrap_err().to_string();
            assert!(e.contains(want), "{want}: {e}");
        }
        let e = check_blink(&blink(), &s, Some(59)).unwrap_err().to_string();
        assert!(e.contains("of a stream of 59 planes"), "{e}");
        let mut empty = s.clone();
        empty.width = 0;
        assert!(check_blink(&blink(), &empty, None).is_err());
        // An "empty" segment that carries counts is not empty.
        let e = BlinkRecord {
            flags: flags::CONTINUATION,
            t_drop: 39,
            planes_summed: 0,
            ..blink()
        };
        assert!(check_blink(&e, &s, None).is_err());
    }
}
