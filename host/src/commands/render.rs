//! `smartagg render`: a localisation table (ThunderSTORM CSV, ours or
//! ThunderSTORM's own; or Picasso HDF5, ours or Picasso's) as a
//! super-resolution image.
//!
//! Each localisation is a normalised Gaussian of standard deviation equal to
//! its uncertainty (ThunderSTORM's "normalized Gaussian"), at least
//! `--min-sigma-nm`; the image covers every localisation with a margin.
//! A Picasso table is in camera pixels: its pixel size comes from
//! `--camera-pixel-nm`, else from `Pixelsize` in its YAML sidecar, and its
//! uncertainty is `sqrt((lpx² + lpy²)/2)`, as the CSV's.
//! `--out x.png`: a figure ([`smartagg_localize::figure`]: `--colormap`, a scale bar
//! and its label in DejaVu Sans unless `--no-scale-bar`, `--saturate`
//! percent of the non-empty pixels saturated, the pixel size in pHYs).
//! `--out x.tif`, or `--tiff x.tif` beside the PNG: the density itself
//! (localisations per pixel) as 32-bit float, no scale bar, with the pixel
//! size in nm where ImageJ/Fiji read it.
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
use smartagg_localize::render::{
    drop_outliers, render, Image, RenderOptions, TablePoints, MAX_PIXELS,
};
use smartagg_localize::table::CsvTable;
use smartagg_localize::LocalizeError;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::setup;
use smartagg_io::output::{refuse_overwriting, same_file, AtomicFile};
use smartagg_localize::figure::{figure_png, Colormap, FigureOptions};
use smartagg_localize::picasso;

/// Arguments of `smartagg render`.
#[derive(clap::Args, Debug)]
pub struct Args {
    // A help attribute, not a doc comment: rustdoc would read "[nm]" as a link.
    #[arg(
        help = "Localisation table: CSV with \"x [nm]\", \"y [nm]\" and \"uncertainty [nm]\" columns, or Picasso HDF5 (/locs with x, y, lpx, lpy in camera pixels)"
    )]
    pub table: PathBuf,
    /// Output image: .png (colour map, scale bar) or .tif (32-bit float density, calibrated in nm for ImageJ/Fiji).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the 32-bit float density (.tif, no scale bar, calibrated in nm for ImageJ/Fiji).
    #[arg(long)]
    pub tiff: Option<PathBuf>,
    /// Output pixel size, nm.
    #[arg(long, default_value_t = 5.0)]
    pub pixel_nm: f64,
    /// Smallest Gaussian σ drawn, nm.
    #[arg(long, default_value_t = 2.0)]
    pub min_sigma_nm: f64,
    /// Percent of non-empty pixels saturated in the PNG.
    #[arg(long, default_value_t = 0.5)]
    pub saturate: f64,
    /// Colour map of the PNG.
    #[arg(long, value_enum, default_value_t = Colormap::Gray)]
    pub colormap: Colormap,
    /// Leave the scale bar and its label out of the PNG.
    #[arg(long)]
    pub no_scale_bar: bool,
    /// Picasso HDF5 input: camera pixel size, nm [default: Pixelsize in its .yaml sidecar].
    #[arg(long, allow_negative_numbers = true, value_parser = |s: &str| setup::ranged(s, 0.1, 1e6, "nm"))]
    pub camera_pixel_nm: Option<f64>,
    /// Also draw failed fits (fit_status ≠ 0).
    #[arg(long)]
    pub include_failed: bool,
}

/// Lower-case extension of a path.
fn ext(p: &Path) -> String {
    p.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// Reads a ThunderSTORM CSV table.
fn read_csv(args: &Args) -> anyhow::Result<TablePoints> {
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
    TablePoints::from_csv(&t, bad_rows.len(), args.include_failed)
        .map_err(|m| anyhow::anyhow!("{} {m}", args.table.display()))
}

/// Reads a Picasso HDF5 table, converting camera pixels to nm.
fn read_hdf5(args: &Args) -> anyhow::Result<TablePoints> {
    let locs = picasso::read(&args.table)?;
    let pixel_nm = match (args.camera_pixel_nm, locs.pixel_nm) {
        (Some(p), _) | (None, Some(p)) => p,
        (None, None) => bail!(
            "{}: give the camera pixel size with --camera-pixel-nm (a Picasso table is in camera pixels, and {} has no Pixelsize)",
            args.table.display(),
            picasso::sidecar_path(&args.table).display()
        ),
    };
    Ok(locs.points(pixel_nm, args.include_failed))
}

/// Writes the density as a calibrated 32-bit float TIFF beside `target`.
fn tiff_file(target: &Path, img: &Image) -> anyhow::Result<AtomicFile> {
    smartagg_localize::error::check_option("pixel-nm", img.pixel_nm, 1e-3, 1e6)?;
    let mut out = BufWriter::new(AtomicFile::create(target)?);
    smartagg_io::image::write_f32_calibrated(
        &mut out,
        img.width,
        img.height,
        &img.data,
        img.pixel_nm,
    )
    .with_context(|| format!("writing {}", target.display()))?;
    out.into_inner()
        .map_err(|e| e.into_error())
        .with_context(|| format!("writing {}", target.display()))
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    // Every output is checked before anything is read or written.
    let sidecar = picasso::sidecar_path(&args.table);
    let inputs: [&Path; 2] = [&args.table, &sidecar];
    refuse_overwriting(&args.out, &inputs)?;
    let out_tiff = match ext(&args.out).as_str() {
        "png" => false,
        "tif" | "tiff" => true,
        _ => bail!(
            "--out {}: the format comes from the extension: .png (figure) or .tif (32-bit density)",
            args.out.display()
        ),
    };
    if let Some(t) = &args.tiff {
        refuse_overwriting(t, &inputs)?;
        if !matches!(ext(t).as_str(), "tif" | "tiff") {
            bail!("--tiff {}: give a .tif file", t.display());
        }
        if t == &args.out || same_file(t, &args.out) {
            bail!("--tiff and --out are the same file, {}", t.display());
        }
    }
    let fig = FigureOptions {
        colormap: args.colormap,
        saturate: args.saturate,
        scale_bar: !args.no_scale_bar,
    };
    smartagg_localize::error::check_option("saturate", args.saturate, 0.0, 100.0)?;
    let TablePoints {
        mut points,
        failed,
        unusable,
        not_numbers,
    } = if picasso::is_hdf5(&args.table) {
        read_hdf5(&args)?
    } else {
        if args.camera_pixel_nm.is_some() {
            bail!("--camera-pixel-nm applies to a Picasso HDF5 table; a CSV table is in nm");
        }
        read_csv(&args)?
    };
    if points.is_empty() {
        bail!(
            "{}: no localisation to render ({} failed fits left out, {} rows without a position, {} rows that are not numbers)",
            args.table.display(),
            failed,
            unusable,
            not_numbers
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
    let (main, what) = if out_tiff {
        (
            tiff_file(&args.out, &img)?,
            "32-bit float density, calibrated in nm".to_string(),
        )
    } else {
        let (bytes, bar) = figure_png(&img, &fig)?;
        let mut f = AtomicFile::create(&args.out)?;
        f.write_all(&bytes)
            .with_context(|| format!("writing {}", args.out.display()))?;
        let what = match bar {
            None if args.no_scale_bar => format!("{:?} PNG, no scale bar", args.colormap),
            None => format!("{:?} PNG, image too small for a scale bar", args.colormap),
            Some(b) if b.font_px == 0 => format!(
                "{:?} PNG, scale bar {} (label too large for the image, bar only)",
                args.colormap, b.label
            ),
            Some(b) => format!(
                "{:?} PNG, scale bar {}, label {} px",
                args.colormap, b.label, b.font_px
            ),
        };
        (f, what.to_lowercase())
    };
    let extra = match &args.tiff {
        Some(t) => Some(tiff_file(t, &img)?),
        None => None,
    };
    main.commit()?;
    if let Some(t) = extra {
        t.commit()?;
    }
    println!(
        "{} localisations rendered to {}{} ({}x{} px at {} nm, origin ({:.0}, {:.0}) nm, {}); {} failed fits left out, {} rows without a position, {} outside, {} outliers left out, {} rows not numbers",
        points.len() - skipped,
        args.out.display(),
        args.tiff
            .as_ref()
            .map(|t| format!(" and {}", t.display()))
            .unwrap_or_default(),
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
        not_numbers
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn defaults() -> Args {
        Args {
            table: PathBuf::new(),
            out: PathBuf::new(),
            tiff: None,
            pixel_nm: 5.0,
            min_sigma_nm: 2.0,
            saturate: 0.5,
            colormap: Colormap::Gray,
            no_scale_bar: false,
            camera_pixel_nm: None,
            include_failed: false,
        }
    }

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
            ..defaults()
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
            ..defaults()
        })
        .unwrap();
        let f = smartagg_io::stack::open_stack(&tif)
            .unwrap()
            .next()
            .unwrap()
            .unwrap();
        let total: f64 = f.data.iter().sum();
        assert!((total - 3.0).abs() < 1e-3, "{total}");
    }

    #[test]
    fn tiff_holds_the_density_with_imagej_calibration_and_png_its_phys() {
        use smartagg_localize::render::Point;
        use tiff::decoder::{Decoder, DecodingResult};
        use tiff::tags::Tag;
        let pts: Vec<Point> = (0..40)
            .map(|k| Point {
                x_nm: 300.0 + 37.0 * k as f64,
                y_nm: 200.0 + 23.0 * (k % 7) as f64,
                sigma_nm: 8.0,
            })
            .collect();
        let o = RenderOptions::covering(&pts, 7.5, 2.0).unwrap();
        let (img, _) = render(&pts, &o).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let tif = dir.path().join("d.tif");
        tiff_file(&tif, &img).unwrap().commit().unwrap();
        let mut d = Decoder::new(std::fs::File::open(&tif).unwrap()).unwrap();
        match d.read_image().unwrap() {
            DecodingResult::F32(v) => assert_eq!(v, img.data, "the values are the image's"),
            _ => panic!("not 32-bit float"),
        }
        // ImageJ: pixel width = 1 / XResolution, unit from the description.
        for tag in [Tag::XResolution, Tag::YResolution] {
            let v = match d.get_tag(tag).unwrap() {
                tiff::decoder::ifd::Value::Rational(n, d) => f64::from(n) / f64::from(d),
                other => panic!("{tag:?} is not a rational: {other:?}"),
            };
            assert!((1.0 / v - 7.5).abs() < 1e-9, "{tag:?} {v}");
        }
        assert_eq!(d.get_tag_u32(Tag::ResolutionUnit).unwrap(), 1);
        let desc = d.get_tag_ascii_string(Tag::ImageDescription).unwrap();
        assert!(
            desc.starts_with("ImageJ=") && desc.contains("\nunit=nm\n"),
            "{desc:?}"
        );

        let opts = FigureOptions {
            colormap: Colormap::Magma,
            saturate: 0.5,
            scale_bar: true,
        };
        let (bytes, _) = figure_png(&img, &opts).unwrap();
        let reader = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .unwrap();
        let info = reader.info();
        assert_eq!(info.color_type, png::ColorType::Rgb);
        let dims = info.pixel_dims.unwrap();
        // 7.5 nm pixels: 133 333 333 per metre.
        assert_eq!((dims.xppu, dims.yppu), (133_333_333, 133_333_333));
        assert_eq!(dims.unit, png::Unit::Meter);
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
                ..defaults()
            })
            .unwrap_err()
        );
        assert!(e.contains("uncertainty [nm]"), "{e}");
    }
}
