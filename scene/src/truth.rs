//! Ground truth: one row per blink, and its CSV file.
//!
//! Columns of the CSV (header line first, comma-separated, `.` decimal point):
//!
//! | column | meaning |
//! |---|---|
//! | `blink` | blink number, in order of start |
//! | `emitter` | emitter identifier (the same molecule blinking again keeps it) |
//! | `x_nm`, `y_nm` | true position, nm from the field's top-left corner (pixel (i, j) centre at ((i+½)p, (j+½)p)) |
//! | `t_on_s`, `t_off_s` | true start and end of the blink, s (start may be negative: on before the recording) |
//! | `flux_hz` | photons/s reaching the sensor during this blink (after the intensity variation) |
//! | `on_exposed_s` | time the blink was on while the camera was exposing (within the simulated planes or frames) |
//! | `photons_emitted` | photons reaching the sensor plane during `on_exposed_s`, inside the field or not |
//! | `photons_detected` | of those, photons detected in the field (SPAD: detections before pile-up, so two in one pixel and plane count 2 though the pixel reads 1; EMCCD/sCMOS: photo-electrons before gain) |
//! | `drift_x_nm`, `drift_y_nm` | only in files of a simulation with stage drift: the drift this blink was imaged with, nm (see [`crate::drift`]); the blink appears at `(x_nm + drift_x_nm, y_nm + drift_y_nm)` |
//!
//! With stage drift, `x_nm`, `y_nm` stay the emitter's position in the
//! sample; a simulation without drift writes the ten columns above only.

use std::io::{BufRead, Write};

use crate::SceneError;

/// The truth about one blink.
#[derive(Debug, Clone, PartialEq)]
pub struct BlinkTruth {
    /// Blink number, in order of start.
    pub blink: u64,
    /// Emitter identifier.
    pub emitter: u64,
    /// True x, nm from the field's left edge.
    pub x_nm: f64,
    /// True y, nm from the field's top edge.
    pub y_nm: f64,
    /// Start of the blink, s.
    pub t_on_s: f64,
    /// End of the blink, s.
    pub t_off_s: f64,
    /// Photons/s reaching the sensor during this blink.
    pub flux_hz: f64,
    /// On-time overlapping the camera's exposures so far, s.
    pub on_exposed_s: f64,
    /// Photons reaching the sensor plane during `on_exposed_s`.
    pub photons_emitted: u64,
    /// Photons detected in the field.
    pub photons_detected: u64,
    /// Stage drift the blink was imaged with, x, nm (0 without drift).
    pub drift_x_nm: f64,
    /// Stage drift the blink was imaged with, y, nm (0 without drift).
    pub drift_y_nm: f64,
}

impl BlinkTruth {
    /// Duration of the blink, s.
    pub fn duration_s(&self) -> f64 {
        self.t_off_s - self.t_on_s
    }

    /// Where the blink was imaged: its position plus the stage drift, nm.
    pub fn imaged_nm(&self) -> (f64, f64) {
        (self.x_nm + self.drift_x_nm, self.y_nm + self.drift_y_nm)
    }
}

/// The CSV header line.
pub const CSV_HEADER: &str =
    "blink,emitter,x_nm,y_nm,t_on_s,t_off_s,flux_hz,on_exposed_s,photons_emitted,photons_detected";

/// The two columns a simulation with stage drift adds after [`CSV_HEADER`]'s.
pub const DRIFT_COLUMNS: &str = "drift_x_nm,drift_y_nm";

/// Writes the ground truth as CSV (header line, one row per blink); the
/// drift columns only if some blink was imaged with drift.
pub fn write_csv<W: Write>(mut w: W, blinks: &[BlinkTruth]) -> Result<(), SceneError> {
    let drift = blinks
        .iter()
        .any(|b| b.drift_x_nm != 0.0 || b.drift_y_nm != 0.0);
    if drift {
        writeln!(w, "{CSV_HEADER},{DRIFT_COLUMNS}")?;
    } else {
        writeln!(w, "{CSV_HEADER}")?;
    }
    for b in blinks {
        // `{}` of f64 prints the shortest representation that parses back exactly.
        write!(
            w,
            "{},{},{},{},{},{},{},{},{},{}",
            b.blink,
            b.emitter,
            b.x_nm,
            b.y_nm,
            b.t_on_s,
            b.t_off_s,
            b.flux_hz,
            b.on_exposed_s,
            b.photons_emitted,
            b.photons_detected
        )?;
        if drift {
            write!(w, ",{},{}", b.drift_x_nm, b.drift_y_nm)?;
        }
        writeln!(w)?;
    }
    w.flush()?;
    Ok(())
}

/// Reads a ground-truth CSV written by [`write_csv`] (with or without the
/// drift columns).
pub fn read_csv<R: BufRead>(r: R) -> Result<Vec<BlinkTruth>, SceneError> {
    let mut out = Vec::new();
    let mut seen_header = false;
    let mut fields = 10;
    let with_drift = format!("{CSV_HEADER},{DRIFT_COLUMNS}");
    for (i, line) in r.lines().enumerate() {
        let line = line?;
        let n = i + 1;
        if n == 1 {
            if line.trim() == with_drift {
                fields = 12;
            } else if line.trim() != CSV_HEADER {
                return Err(SceneError::TruthCsv {
                    line: 1,
                    why: format!(
                        "expected the header `{CSV_HEADER}` (with `,{DRIFT_COLUMNS}` after a simulation with drift)"
                    ),
                });
            }
            seen_header = true;
            continue;
        }
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != fields {
            return Err(SceneError::TruthCsv {
                line: n,
                why: format!("{} fields, expected {fields}", f.len()),
            });
        }
        let int = |k: usize| -> Result<u64, SceneError> {
            f[k].trim().parse().map_err(|_| SceneError::TruthCsv {
                line: n,
                why: format!("field {} `{}` is not an unsigned integer", k + 1, f[k]),
            })
        };
        let real = |k: usize| -> Result<f64, SceneError> {
            let v: f64 = f[k].trim().parse().map_err(|_| SceneError::TruthCsv {
                line: n,
                why: format!("field {} `{}` is not a number", k + 1, f[k]),
            })?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(SceneError::TruthCsv {
                    line: n,
                    why: format!("field {} is not finite", k + 1),
                })
            }
        };
        out.push(BlinkTruth {
            blink: int(0)?,
            emitter: int(1)?,
            x_nm: real(2)?,
            y_nm: real(3)?,
            t_on_s: real(4)?,
            t_off_s: real(5)?,
            flux_hz: real(6)?,
            on_exposed_s: real(7)?,
            photons_emitted: int(8)?,
            photons_detected: int(9)?,
            drift_x_nm: if fields == 12 { real(10)? } else { 0.0 },
            drift_y_nm: if fields == 12 { real(11)? } else { 0.0 },
        });
    }
    if !seen_header {
        return Err(SceneError::TruthCsv {
            line: 1,
            why: "the file is empty (no header line)".into(),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_is_exact() {
        let b = BlinkTruth {
            blink: 3,
            emitter: 7,
            x_nm: 123.456789012345,
            y_nm: 1e-7,
            t_on_s: -0.0123,
            t_off_s: 0.1 + 0.2,
            flux_hz: 50_000.0,
            on_exposed_s: 0.3,
            photons_emitted: 15_000,
            photons_detected: 1_234,
            drift_x_nm: 0.0,
            drift_y_nm: 0.0,
        };
        let mut v = Vec::new();
        write_csv(&mut v, std::slice::from_ref(&b)).unwrap();
        assert!(std::str::from_utf8(&v)
            .unwrap()
            .starts_with(&format!("{CSV_HEADER}\n")));
        let back = read_csv(&v[..]).unwrap();
        assert_eq!(back, vec![b.clone()]);
        let drifted = BlinkTruth {
            drift_x_nm: -12.5,
            drift_y_nm: 3.0e-3,
            ..b
        };
        let mut v = Vec::new();
        write_csv(&mut v, std::slice::from_ref(&drifted)).unwrap();
        assert!(std::str::from_utf8(&v).unwrap().contains(DRIFT_COLUMNS));
        assert_eq!(read_csv(&v[..]).unwrap(), vec![drifted]);
    }

    #[test]
    fn bad_lines_are_named() {
        assert!(read_csv(&b""[..])
            .unwrap_err()
            .to_string()
            .contains("empty"));
        let e = read_csv(&b"nope\n"[..]).unwrap_err();
        assert!(e.to_string().contains("line 1"));
        let text = format!("{CSV_HEADER}\n1,2,3,4,5,6,7,8,9\n");
        let e = read_csv(text.as_bytes()).unwrap_err();
        assert!(
            e.to_string().contains("line 2") && e.to_string().contains("9 fields"),
            "{e}"
        );
        let text = format!("{CSV_HEADER}\n1,2,x,4,5,6,7,8,9,10\n");
        let e = read_csv(text.as_bytes()).unwrap_err();
        assert!(e.to_string().contains("`x`"), "{e}");
    }
}
