//! Localisation tables in ThunderSTORM's CSV layout.
//!
//! The first nine columns are exactly ThunderSTORM's, so the table opens in
//! ThunderSTORM ("Import results"), in Picasso's and SMAP's ThunderSTORM
//! importers:
//!
//! `"id","frame","x [nm]","y [nm]","sigma [nm]","intensity [photon]","offset [photon]","bkgstd [photon]","uncertainty [nm]"`
//!
//! then `"fit_status"` (0 = ok; the codes of [`FitStatus`]): a failed fit is
//! kept, flagged, with finite values — never dropped silently and never NaN.
//! Merged tables add ThunderSTORM's `"detections"` column; blink-ROI tables
//! add their timing columns (see the callers).
//!
//! `uncertainty [nm]` is `sqrt((var_x + var_y)/2)` of the estimator's
//! precision (the Cramér–Rao bound of the fitted model for the MLEs).

use crate::error::LocalizeError;
use crate::fit::{Fit, FitStatus};
use std::io::{BufRead, Read, Write};

/// ThunderSTORM's column names, in order.
pub const THUNDERSTORM_COLUMNS: [&str; 9] = [
    "id",
    "frame",
    "x [nm]",
    "y [nm]",
    "sigma [nm]",
    "intensity [photon]",
    "offset [photon]",
    "bkgstd [photon]",
    "uncertainty [nm]",
];

/// Name of the status column appended after ThunderSTORM's.
pub const STATUS_COLUMN: &str = "fit_status";
/// ThunderSTORM's column for the number of merged detections.
pub const DETECTIONS_COLUMN: &str = "detections";

/// One localisation in sample coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct Localization {
    /// Frame (1-based for frame stacks; the blink index for ROI streams).
    pub frame: u64,
    /// x, nm.
    pub x_nm: f64,
    /// y, nm.
    pub y_nm: f64,
    /// PSF σ, nm.
    pub sigma_nm: f64,
    /// Photons from the emitter.
    pub intensity: f64,
    /// Background photons per pixel.
    pub offset: f64,
    /// Background noise per pixel, photons.
    pub bkgstd: f64,
    /// `sqrt((var_x + var_y)/2)`, nm.
    pub uncertainty_nm: f64,
    /// Fit outcome.
    pub status: FitStatus,
    /// Detections merged into this one (1 if not merged).
    pub detections: u32,
    /// Values of the table's extra columns.
    pub extra: Vec<f64>,
}

impl Localization {
    /// A localisation from a fit in an ROI whose top-left pixel is at sensor
    /// pixel `(x0, y0)`: position `(x0 + x) · pixel_nm` (pixel `i` spans
    /// `[i, i+1)`, the ImageJ/ThunderSTORM convention).
    pub fn from_fit(fit: &Fit, x0: f64, y0: f64, pixel_nm: f64, frame: u64) -> Localization {
        let f = fit.sanitized(0);
        Localization {
            frame,
            x_nm: (x0 + f.x) * pixel_nm,
            y_nm: (y0 + f.y) * pixel_nm,
            sigma_nm: f.sigma * pixel_nm,
            intensity: f.photons,
            offset: f.background,
            bkgstd: f.bkgstd,
            uncertainty_nm: f.uncertainty_px() * pixel_nm,
            status: f.status,
            detections: 1,
            extra: Vec::new(),
        }
    }
}

/// A localisation table with optional extra columns.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LocTable {
    /// Names of the columns after `fit_status` (and `detections`).
    pub extra_columns: Vec<String>,
    /// Whether the `detections` column is written (merged tables).
    pub merged: bool,
    /// The rows; `id` is the 1-based row number.
    pub rows: Vec<Localization>,
}

impl LocTable {
    /// Number of rows whose fit failed.
    pub fn failures(&self) -> usize {
        self.rows.iter().filter(|r| !r.status.is_ok()).count()
    }

    /// Writes the table as CSV.
    pub fn write_csv<W: Write>(&self, w: &mut W) -> std::io::Result<()> {
        let mut header: Vec<String> = THUNDERSTORM_COLUMNS
            .iter()
            .map(|c| format!("\"{c}\""))
            .collect();
        header.push(format!("\"{STATUS_COLUMN}\""));
        if self.merged {
            header.push(format!("\"{DETECTIONS_COLUMN}\""));
        }
        for c in &self.extra_columns {
            header.push(format!("\"{}\"", c.replace('"', "'")));
        }
        writeln!(w, "{}", header.join(","))?;
        // Rows are formatted in parallel runs (float formatting is most of
        // the cost of a large table), then written in order.
        use rayon::prelude::*;
        const RUN: usize = 4096;
        let runs: Vec<Vec<u8>> = self
            .rows
            .par_chunks(RUN)
            .enumerate()
            .map(|(c, rows)| {
                let mut out = Vec::with_capacity(rows.len() * 96);
                let mut tmp = String::new();
                for (k, r) in rows.iter().enumerate() {
                    self.format_row(c * RUN + k + 1, r, &mut out, &mut tmp);
                }
                out
            })
            .collect();
        for run in runs {
            w.write_all(&run)?;
        }
        Ok(())
    }

    /// Appends row `id` (1-based) to `out`; `tmp` is scratch.
    fn format_row(&self, id: usize, r: &Localization, out: &mut Vec<u8>, tmp: &mut String) {
        use std::fmt::Write as _;
        tmp.clear();
        let _ = write!(tmp, "{id},{},", r.frame);
        out.extend_from_slice(tmp.as_bytes());
        for (v, d) in [
            (r.x_nm, 3),
            (r.y_nm, 3),
            (r.sigma_nm, 3),
            (r.intensity, 2),
            (r.offset, 3),
            (r.bkgstd, 3),
            (r.uncertainty_nm, 3),
        ] {
            push_num(out, tmp, v, d);
            out.push(b',');
        }
        tmp.clear();
        let _ = write!(tmp, "{}", r.status.code());
        if self.merged {
            let _ = write!(tmp, ",{}", r.detections);
        }
        out.extend_from_slice(tmp.as_bytes());
        for k in 0..self.extra_columns.len() {
            out.push(b',');
            push_num(out, tmp, r.extra.get(k).copied().unwrap_or(0.0), 3);
        }
        out.push(b'\n');
    }
}

/// Appends `v` with `digits` decimals, trailing zeros trimmed, to `out`
/// (`tmp` is scratch). Values reaching here are finite (fits are
/// sanitised); anything else is written as 0 so that no NaN can enter a
/// table.
fn push_num(out: &mut Vec<u8>, tmp: &mut String, v: f64, digits: usize) {
    use std::fmt::Write as _;
    if !v.is_finite() {
        out.push(b'0');
        return;
    }
    tmp.clear();
    let _ = write!(tmp, "{v:.digits$}");
    let mut s = tmp.as_str();
    if s.contains('.') {
        s = s.trim_end_matches('0').trim_end_matches('.');
    }
    if s == "-0" {
        s = "0";
    }
    out.extend_from_slice(s.as_bytes());
}

/// `v` with `digits` decimals, trailing zeros trimmed, as the tables write
/// it (a non-finite value is written as 0).
pub fn format_decimal(v: f64, digits: usize) -> String {
    let mut out = Vec::new();
    push_num(&mut out, &mut String::new(), v, digits);
    String::from_utf8(out).expect("ASCII")
}

#[cfg(test)]
fn num(v: f64, digits: usize) -> String {
    format_decimal(v, digits)
}

/// Longest line [`CsvTable::read`] accepts, bytes (a localisation row is
/// about 100 bytes).
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// A column a table lacks: the names it may go by, and the table's columns.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("has no column {} (columns: {})", names.iter().map(|n| format!("\"{n}\"")).collect::<Vec<_>>().join(" or "), columns.join(", "))]
pub struct MissingColumn {
    /// The names the column may go by.
    pub names: &'static [&'static str],
    /// The table's columns.
    pub columns: Vec<String>,
}

/// A numeric table read from CSV: column names and rows of numbers.
#[derive(Clone, Debug, PartialEq)]
pub struct CsvTable {
    /// Column names, quotes removed.
    pub columns: Vec<String>,
    /// Rows of values.
    pub rows: Vec<Vec<f64>>,
}

impl CsvTable {
    /// `text`, the CSV this table was read from, with columns `cx` and `cy`
    /// of every data row replaced by `x − dx`, `y − dy` (`(dx, dy) =
    /// shift(row)`), every other byte kept: a table corrected in place
    /// (drift). Rows are found as [`CsvTable::read`] finds them (the first
    /// non-blank line is the header, blank lines skipped).
    pub fn rewrite_xy(
        &self,
        text: &[u8],
        cx: usize,
        cy: usize,
        shift: impl Fn(&[f64]) -> (f64, f64),
    ) -> Result<Vec<u8>, LocalizeError> {
        let text =
            std::str::from_utf8(text).map_err(|_| LocalizeError::Rewrite("not UTF-8 text"))?;
        let mut out = String::with_capacity(text.len() + text.len() / 8);
        let mut header_seen = false;
        let mut rows = self.rows.iter();
        for line in text.split_inclusive('\n') {
            let content = line.trim_end_matches(['\n', '\r']);
            let ending = &line[content.len()..];
            if content.trim_start_matches('\u{feff}').trim().is_empty() || !header_seen {
                header_seen |= !content.trim_start_matches('\u{feff}').trim().is_empty();
                out.push_str(line);
                continue;
            }
            let r = rows
                .next()
                .ok_or(LocalizeError::Rewrite("more rows than the table read"))?;
            let (dx, dy) = shift(r);
            let mut fields: Vec<String> = content.split(',').map(str::to_string).collect();
            let keep_space = |old: &str, new: String| {
                // Keep any padding around the number.
                let lead = &old[..old.len() - old.trim_start().len()];
                let trail = &old[old.trim_end().len()..];
                format!("{lead}{new}{trail}")
            };
            fields[cx] = keep_space(&fields[cx], format_decimal(r[cx] - dx, 3));
            fields[cy] = keep_space(&fields[cy], format_decimal(r[cy] - dy, 3));
            out.push_str(&fields.join(","));
            out.push_str(ending);
        }
        if rows.next().is_some() {
            return Err(LocalizeError::Rewrite("fewer rows than the table read"));
        }
        Ok(out.into_bytes())
    }

    /// Index of the first column with one of these names.
    pub fn column(&self, names: &[&str]) -> Option<usize> {
        names
            .iter()
            .find_map(|n| self.columns.iter().position(|c| c.eq_ignore_ascii_case(n)))
    }

    /// [`CsvTable::column`], or an error that names the column sought and
    /// the table's columns.
    pub fn require(&self, names: &'static [&'static str]) -> Result<usize, MissingColumn> {
        self.column(names).ok_or_else(|| MissingColumn {
            names,
            columns: self.columns.clone(),
        })
    }

    /// Reads a numeric CSV table (comma separated, header first, quoted or
    /// plain names). Blank lines are skipped; a wrong field count, a value
    /// that is not a number or a line longer than [`MAX_LINE_BYTES`] (not a
    /// table: `/dev/zero`, a binary file) is an error naming the line.
    pub fn read<R: BufRead>(reader: R) -> Result<CsvTable, LocalizeError> {
        Self::read_inner(reader, None)
    }

    /// Reads a table like [`CsvTable::read`], but skips the rows with a
    /// wrong field count or a value that is not a number instead of failing:
    /// returns the table and the skipped rows (line number, why). A line too
    /// long or not text is still an error (the file is not a table).
    pub fn read_skipping_bad_rows<R: BufRead>(
        reader: R,
    ) -> Result<(CsvTable, Vec<(usize, String)>), LocalizeError> {
        let mut skipped = Vec::new();
        let t = Self::read_inner(reader, Some(&mut skipped))?;
        Ok((t, skipped))
    }

    fn read_inner<R: BufRead>(
        mut reader: R,
        mut skipped: Option<&mut Vec<(usize, String)>>,
    ) -> Result<CsvTable, LocalizeError> {
        let mut columns: Option<Vec<String>> = None;
        let mut rows = Vec::new();
        let mut raw = Vec::new();
        for i in 0.. {
            raw.clear();
            let got = (&mut reader)
                .take(MAX_LINE_BYTES as u64 + 1)
                .read_until(b'\n', &mut raw)?;
            if got == 0 {
                break;
            }
            if raw.len() > MAX_LINE_BYTES {
                return Err(LocalizeError::Table {
                    line: i + 1,
                    why: format!(
                        "longer than {MAX_LINE_BYTES} bytes without a line break: not a CSV table"
                    ),
                });
            }
            let line = std::str::from_utf8(&raw).map_err(|_| LocalizeError::Table {
                line: i + 1,
                why: "not UTF-8 text: not a CSV table".into(),
            })?;
            let line = line.trim_start_matches('\u{feff}').trim();
            if line.is_empty() {
                continue;
            }
            let fields: Vec<&str> = line
                .split(',')
                .map(|f| f.trim().trim_matches('"'))
                .collect();
            match &columns {
                None => columns = Some(fields.iter().map(|f| f.to_string()).collect()),
                Some(cols) => {
                    let parsed = if fields.len() != cols.len() {
                        Err(format!(
                            "{} fields, the header has {}",
                            fields.len(),
                            cols.len()
                        ))
                    } else {
                        fields
                            .iter()
                            .zip(cols)
                            .map(|(f, c)| {
                                f.parse::<f64>()
                                    .map_err(|_| format!("column \"{c}\": `{f}` is not a number"))
                            })
                            .collect::<Result<Vec<f64>, String>>()
                    };
                    match (parsed, skipped.as_deref_mut()) {
                        (Ok(row), _) => rows.push(row),
                        (Err(why), Some(list)) => list.push((i + 1, why)),
                        (Err(why), None) => return Err(LocalizeError::Table { line: i + 1, why }),
                    }
                }
            }
        }
        let columns = columns.ok_or(LocalizeError::Table {
            line: 1,
            why: "empty file: no header".into(),
        })?;
        Ok(CsvTable { columns, rows })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_bounded_and_bad_rows_can_be_skipped() {
        let zeros = std::io::Read::take(std::io::repeat(0), 64 << 20);
        let e = CsvTable::read(std::io::BufReader::new(zeros)).unwrap_err();
        assert!(e.to_string().contains("not a CSV table"), "{e}");
        let text = "\"a\",\"b\"\n1,2\nx,3\n4\n5,6\n";
        assert!(CsvTable::read(text.as_bytes()).is_err());
        let (t, bad) = CsvTable::read_skipping_bad_rows(text.as_bytes()).unwrap();
        assert_eq!(t.rows, vec![vec![1.0, 2.0], vec![5.0, 6.0]]);
        assert_eq!(bad.iter().map(|b| b.0).collect::<Vec<_>>(), [3, 4]);
    }

    #[test]
    fn number_format_is_finite_and_trimmed() {
        assert_eq!(num(1.5, 3), "1.5");
        assert_eq!(num(2.0, 3), "2");
        assert_eq!(num(-0.0001, 3), "0");
        assert_eq!(num(f64::NAN, 3), "0");
        assert_eq!(num(1234.56789, 2), "1234.57");
    }

    #[test]
    fn rewriting_changes_x_and_y_only() {
        let text = "\u{feff}\"id\",\"frame\",\"x [nm]\",\"y [nm]\",\"q\"\r\n\r\n1,3,100.5,200,7.125\r\n2,4, 10 ,20,8\n";
        let t = CsvTable::read(text.as_bytes()).unwrap();
        let out = t
            .rewrite_xy(text.as_bytes(), 2, 3, |r| (r[1], -1.0))
            .unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "\u{feff}\"id\",\"frame\",\"x [nm]\",\"y [nm]\",\"q\"\r\n\r\n1,3,97.5,201,7.125\r\n2,4, 6 ,21,8\n"
        );
        // A text that is not the table's is refused, not half rewritten.
        let e = t.rewrite_xy(b"a,b\n1,2\n", 0, 1, |_| (0.0, 0.0));
        assert!(matches!(e, Err(LocalizeError::Rewrite(_))), "{e:?}");
    }
}
