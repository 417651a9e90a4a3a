//! `smartagg render`: a localisation table (ThunderSTORM CSV, ours or
//! ThunderSTORM's own) as a super-resolution image.
//!
//! Each localisation is a normalised Gaussian of standard deviation equal to
//! its uncertainty (ThunderSTORM's "normalized Gaussian"), at least
//! `--min-sigma-nm`; the image covers every localisation with a margin.
//! `--out x.png`: 8-bit grey with a scale bar and its label (`--saturate`
//! percent of the non-empty pixels saturated). `--out x.tif`: the density
//! itself (localisations per pixel) as 32-bit float, for ImageJ/Fiji.
//! Failed fits (`fit_status` ≠ 0) are left out unless `--include-failed`;
//! rows without a usable position are counted and reported.
//!
//! A hostile table does not sink the rest (issue 36): rows that do not
//! parse are skipped and counted, and so are outliers far from the others
//! (a position or uncertainty that would make the image larger than
//! [`MAX_PIXELS`]); only a table with no usable row is an error. The image
//! is written beside its target and renamed into place when complete, and
//! never over the table itself.

use anyhow::{bail, Context};
use smartagg_localize::render::{render, to_png, Point, RenderOptions, MAX_PIXELS};
use smartagg_localize::table::CsvTable;
use smartagg_localize::{tiffio, LocalizeError};
use std::io::{BufWriter, Write};
use std::path::PathBuf;

use crate::output::{refuse_overwriting, AtomicFile};

/// Leaves out the points too far from the median position (or too blurred)
/// for one image of at most [`MAX_PIXELS`] pixels at `pixel_nm`; returns
/// how many were left out.
fn drop_outliers(points: &mut Vec<Point>, pixel_nm: f64) -> usize {
    let median = |f: fn(&Point) -> f64| {
        let mut v: Vec<f64> = points.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (mx, my) = (median(|p| p.x_nm), median(|p| p.y_nm));
    // A square image of MAX_PIXELS, with room for the margins.
    let half = 0.35 * (MAX_PIXELS as f64).sqrt() * pixel_nm;
    let before = points.len();
    points.retain(|p| {
        (p.x_nm - mx).abs() <= half && (p.y_nm - my).abs() <= half && p.sigma_nm <= half / 8.0
    });
    before - points.len()
}

/// Arguments of `smartagg render`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Localisation table (CSV with "x [nm]", "y [nm]" and "uncertainty [nm]" columns).
    pub table: PathBuf,
    /// Output image: .png (8-bit, scale bar) or .tif (32-bit float density).
    #[arg(long)]
    pub out: PathBuf,
    /// Output pixel size, nm.
    #[arg(long, default_value_t = 5.0)]
    pub pixel_nm: f64,
    /// Smallest Gaussian σ drawn, nm.
    #[arg(long, default_value_t = 2.0)]
    pub min_sigma_nm: f64,
    /// Percent of non-empty pixels saturated in the PNG.
    #[arg(long, default_value_t = 0.5)]
    pub saturate: f64,
    /// Also draw failed fits (fit_status ≠ 0).
    #[arg(long)]
    pub include_failed: bool,
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    refuse_overwriting(&args.out, &[&args.table])?;
    let file = std::fs::File::open(&args.table)
        .with_context(|| format!("opening {}", args.table.display()))?;
    let (t, bad_rows) = CsvTable::read_skipping_bad_rows(std::io::BufReader::new(file))
        .with_context(|| format!("reading {}", args.table.display()))?;
    if let Some((line, why)) = bad_rows.first() {
        eprintln!(
            "smartagg: warning: {}: {} rows skipped that are not rows of numbers (first: line {line}: {why})",
            args.table.display(),
            bad_rows.len()
        );
    }
    let col = |names: &[&str]| -> anyhow::Result<usize> {
        t.column(names).with_context(|| {
            format!(
                "{} has no column {} (columns: {})",
                args.table.display(),
                names
                    .iter()
                    .map(|n| format!("\"{n}\""))
                    .collect::<Vec<_>>()
                    .join(" or "),
                t.columns.join(", ")
            )
        })
    };
    let (cx, cy) = (col(&["x [nm]"])?, col(&["y [nm]"])?);
    let cu = col(&[
        "uncertainty [nm]",
        "uncertainty_xy [nm]",
        "uncertainty_xy",
        "uncertainty",
    ])?;
    let cs = t.column(&["fit_status"]);
    let mut points = Vec::with_capacity(t.rows.len());
    let (mut failed, mut unusable) = (0usize, 0usize);
    for r in &t.rows {
        if let Some(c) = cs {
            if r[c] != 0.0 && !args.include_failed {
                failed += 1;
                continue;
            }
        }
        let p = Point {
            x_nm: r[cx],
            y_nm: r[cy],
            sigma_nm: r[cu],
        };
        if !(p.x_nm.is_finite() && p.y_nm.is_finite()) {
            unusable += 1;
            continue;
        }
        points.push(p);
    }
    if points.is_empty() {
        bail!(
            "{}: no localisation to render ({} failed fits left out, {} rows without a position, {} rows that are not numbers)",
            args.table.display(),
            failed,
            unusable,
            bad_rows.len()
        );
    }
    let mut outliers = 0;
    let opts = match RenderOptions::covering(&points, args.pixel_nm, args.min_sigma_nm) {
        Ok(o) => o,
        Err(LocalizeError::ImageTooLarge { .. }) => {
            outliers = drop_outliers(&mut points, args.pixel_nm);
            if points.is_empty() {
                bail!(
                    "{}: no localisation to render: the {outliers} positions are spread wider than one image of {MAX_PIXELS} pixels at --pixel-nm {} nm",
                    args.table.display(),
                    args.pixel_nm
                );
            }
            eprintln!(
                "smartagg: warning: {}: {outliers} localisations far from the others (or with a huge uncertainty) left out: with them the image would exceed {MAX_PIXELS} pixels",
                args.table.display()
            );
            RenderOptions::covering(&points, args.pixel_nm, args.min_sigma_nm)?
        }
        Err(e) => return Err(e.into()),
    };
    let (img, skipped) = render(&points, &opts)?;
    let ext = args
        .out
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let mut out = BufWriter::new(AtomicFile::create(&args.out)?);
    let what = if ext == "tif" || ext == "tiff" {
        tiffio::write_f32(&mut out, img.width, img.height, &img.data)
            .with_context(|| format!("writing {}", args.out.display()))?;
        "32-bit float density".to_string()
    } else {
        let (bytes, bar) = to_png(&img, args.saturate)?;
        out.write_all(&bytes)
            .with_context(|| format!("writing {}", args.out.display()))?;
        format!(
            "8-bit PNG, scale bar {}{}",
            bar.label,
            if bar.label_drawn {
                ""
            } else {
                " (label too large for the image, bar only)"
            }
        )
    };
    out.into_inner()
        .map_err(|e| e.into_error())
        .with_context(|| format!("writing {}", args.out.display()))?
        .commit()?;
    println!(
        "{} localisations rendered to {} ({}x{} px at {} nm, origin ({:.0}, {:.0}) nm, {}); {} failed fits left out, {} rows without a position, {} outside, {} outliers left out, {} rows not numbers",
        points.len() - skipped,
        args.out.display(),
        img.width,
        img.height,
        args.pixel_nm,
        img.origin_x_nm,
        img.origin_y_nm,
        what,
        failed,
        unusable,
        skipped,
        outliers,
        bad_rows.len()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_a_table_to_png_and_tiff() {
        let dir = tempfile::tempdir().unwrap();
        let table = dir.path().join("t.csv");
        std::fs::write(
            &table,
            "\"id\",\"frame\",\"x [nm]\",\"y [nm]\",\"sigma [nm]\",\"intensity [photon]\",\"offset [photon]\",\"bkgstd [photon]\",\"uncertainty [nm]\",\"fit_status\"\n\
             1,1,500,400,80,200,5,2,10,0\n\
             2,1,600,420,80,200,5,2,12,0\n\
             3,2,900,900,80,0,5,2,30,5\n",
        )
        .unwrap();
        let png_path = dir.path().join("img.png");
        run(Args {
            table: table.clone(),
            out: png_path.clone(),
            pixel_nm: 5.0,
            min_sigma_nm: 2.0,
            saturate: 0.5,
            include_failed: false,
        })
        .unwrap();
        let dec = png::Decoder::new(std::fs::File::open(&png_path).unwrap());
        let mut reader = dec.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        // The failed fit at (900, 900) is left out: the image ends well before it.
        assert!(
            info.width < 60 && info.height < 60,
            "{}x{}",
            info.width,
            info.height
        );
        let tif = dir.path().join("img.tif");
        run(Args {
            table,
            out: tif.clone(),
            pixel_nm: 5.0,
            min_sigma_nm: 2.0,
            saturate: 0.5,
            include_failed: true,
        })
        .unwrap();
        let f = tiffio::open_stack(&tif).unwrap().next().unwrap().unwrap();
        let total: f64 = f.data.iter().sum();
        assert!((total - 3.0).abs() < 1e-3, "{total}");
    }

    #[test]
    fn missing_columns_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let table = dir.path().join("t.csv");
        std::fs::write(&table, "\"x [nm]\",\"y [nm]\"\n1,2\n").unwrap();
        let e = format!(
            "{:#}",
            run(Args {
                table,
                out: dir.path().join("o.png"),
                pixel_nm: 5.0,
                min_sigma_nm: 2.0,
                saturate: 0.5,
                include_failed: false,
            })
            .unwrap_err()
        );
        assert!(e.contains("uncertainty [nm]"), "{e}");
    }
}
