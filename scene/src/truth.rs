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
}

impl BlinkTruth {
    /// Duration of the blink, s.
    pub fn duration_s(&self) -> f64 {
        self.t_off_s - self.t_on_s
    }
}

/// The CSV header line.
pub const CSV_HEADER: &str =
    "blink,emitter,x_nm,y_nm,t_on_s,t_off_s,flux_hz,on_exposed_s,photons_emitted,photons_detected";

/// Writes the ground truth as CSV (header line, one row per blink).
pub fn write_csv<W: Write>(mut w: W, blinks: &[BlinkTruth]) -> Result<(), SceneError> {
    writeln!(w, "{CSV_HEADER}")?;
    for b in blinks {
        // `{}` of f64 prints the shortest representation that parses back exactly.
        writeln!(
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
    }
    w.flush()?;
    Ok(())
}

/// Reads a ground-truth CSV written by [`write_csv`].
pub fn read_csv<R: BufRead>(r: R) -> Result<Vec<BlinkTruth>, SceneError> {
    let mut out = Vec::new();
    let mut seen_header = false;
    for (i, line) in r.lines().enumerate() {
        let line = line?;
        let n = i + 1;
        if n == 1 {
            if line.trim() != CSV_HEADER {
                return Err(SceneError::TruthCsv {
                    line: 1,
                    why: format!("expected the header `{CSV_HEADER}`"),
                });
            }
            seen_header = true;
            continue;
        }
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 10 {
            return Err(SceneError::TruthCsv {
                line: n,
                why: format!("{} fields, expected 10", f.len()),
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
        };
        let mut v = Vec::new();
        write_csv(&mut v, std::slice::from_ref(&b)).unwrap();
        let back = read_csv(&v[..]).unwrap();
        assert_eq!(back, vec![b]);
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
