//! Packet streams (`.rois`): reading and checking them, fitting each blink's ROI,
//! and the TIFF export of the ROIs.

use super::*;

/// What a packet stream delivered, checked: its first StreamStart, the
/// blink records worth fitting, and every reason the stream is not whole.
pub struct StreamContent {
    /// The first StreamStart (it describes the stream).
    pub start: Option<StreamStart>,
    /// Blink records, in stream order, without duplicates, implausible
    /// records or empty segments.
    pub rois: Vec<BlinkRecord>,
    /// Sentences, one per problem (empty: the stream arrived whole).
    pub problems: Vec<String>,
    /// Empty segments (continuations cut on their last plane): nothing to fit.
    pub empty_segments: usize,
    /// Bit-planes of the stream, from its last StreamEnd.
    pub planes: Option<u64>,
}

/// Reads and checks a packet stream: prints the decoder's loss accounting,
/// drops repeated packets (same sequence number, same record), rejects
/// records the stream's configuration cannot produce
/// (`smartagg_model::record_check`), and cross-checks the StreamEnd totals.
pub fn read_stream(path: &Path) -> anyhow::Result<StreamContent> {
    let meta = std::fs::metadata(path).with_context(|| format!("reading {}", path.display()))?;
    if !meta.is_file() {
        bail!(
            "{} is not a regular file: localize reads a recorded stream (`smartagg download` records a live one)",
            path.display()
        );
    }
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let decoded = smartagg_model::packet::decode_all(&bytes);
    eprintln!("{}: {}", path.display(), decoded.stats);
    let mut problems = Vec::new();
    if decoded.stats.any_loss() {
        problems.push(format!("the decoder lost data: {}", decoded.stats));
    }
    let mut start: Option<StreamStart> = None;
    let mut ends: Vec<smartagg_model::record::StreamEnd> = Vec::new();
    let mut repeats = RepeatFilter::default();
    let (mut received, mut empty_segments) = (0u64, 0usize);
    let (mut rejected, mut examples) = (0usize, Vec::new());
    let mut blinks = Vec::new();
    for p in decoded.packets {
        // A packet repeated by the transport (or a capture concatenated with
        // itself) has the same sequence number and the same record.
        if repeats.is_repeat(p.seq, &p.record) {
            continue;
        }
        match p.record {
            Record::Start(s) if start.is_none() => start = Some(s),
            Record::Blink(b) => {
                received += 1;
                blinks.push(b);
            }
            Record::End(e) => ends.push(e),
            _ => {}
        }
    }
    if blinks.is_empty() && decoded.stats.packets_ok == 0 {
        bail!(
            "{} holds no packets: it is neither a blink-ROI packet stream nor a TIFF",
            path.display()
        );
    }
    let duplicates = repeats.repeats();
    if duplicates > 0 {
        problems.push(format!(
            "{duplicates} repeated packets (same sequence number and content) dropped"
        ));
    }
    let planes = ends.last().map(|e| e.planes);
    let mut rois = Vec::with_capacity(blinks.len());
    match &start {
        None => {
            problems.push(
                "no StreamStart record: the records cannot be checked against the stream's configuration"
                    .into(),
            );
            for b in blinks {
                if is_empty_segment(&b) {
                    empty_segments += 1;
                } else {
                    rois.push(b);
                }
            }
        }
        Some(st) => {
            for b in blinks {
                // Only a single stream's plane count bounds its records.
                let bound = if ends.len() == 1 { planes } else { None };
                match check_blink(&b, st, bound) {
                    Err(e) => {
                        rejected += 1;
                        if examples.len() < 3 {
                            examples.push(format!(
                                "slot {} at ({}, {}), t_cross {}: {e}",
                                b.slot, b.anchor_x, b.anchor_y, b.t_cross
                            ));
                        }
                    }
                    Ok(()) if is_empty_segment(&b) => empty_segments += 1,
                    Ok(()) => rois.push(b),
                }
            }
        }
    }
    if rejected > 0 {
        problems.push(format!(
            "{rejected} blink records that the stream's configuration cannot produce were rejected, not fitted (e.g. {})",
            examples.join("; ")
        ));
    }
    if ends.is_empty() {
        problems.push("no StreamEnd record: the stream was cut short".into());
    } else if !decoded.stats.any_loss() && duplicates == 0 {
        let claimed: u64 = ends.iter().map(|e| e.blinks).fold(0, u64::saturating_add);
        if claimed != received {
            problems.push(format!(
                "the StreamEnd records count {claimed} blinks but {received} arrived"
            ));
        }
    }
    Ok(StreamContent {
        start,
        rois,
        problems,
        empty_segments,
        planes,
    })
}

pub(super) fn localize_rois(args: &Args, s: &Setup) -> anyhow::Result<(LocTable, usize, Extent)> {
    let StreamContent {
        start,
        rois,
        problems,
        empty_segments,
        planes,
    } = read_stream(&args.input)?;
    if !problems.is_empty() {
        if !args.allow_loss || rois.is_empty() {
            let mut msg = format!(
                "{} is not a whole stream:\n  - {}",
                args.input.display(),
                problems.join("\n  - ")
            );
            msg += if rois.is_empty() {
                "\nnothing left to localise"
            } else {
                "\n(--allow-loss localises the records that arrived)"
            };
            bail!(msg);
        }
        for p in &problems {
            eprintln!("smartagg: WARNING: {p}");
        }
    }
    if empty_segments > 0 {
        eprintln!("{empty_segments} empty segments (a continuation cut on its last plane sums no plane): nothing to fit");
    }
    if let (Some(st), Some(info)) = (&start, &s.sidecar) {
        if (u32::from(st.width), u32::from(st.height)) != (info.width, info.height) {
            bail!(
                "the stream's sensor is {}x{} but its sidecar {} says {}x{}: give the camera with --preset or --pixel-nm",
                st.width,
                st.height,
                StreamInfo::path_for(&args.input).display(),
                info.width,
                info.height
            );
        }
    }
    // The maps and the plane period their dark-count rates are read with:
    // the stream's, or the calibration's exposure when the stream has none.
    let (maps, plane_period_s) = match &args.calibration {
        None => (None, 0.0),
        Some(dir) => match AnyCalibration::load(dir)
            .with_context(|| format!("loading calibration {}", dir.display()))?
        {
            AnyCalibration::Spad(c) => {
                let period = start
                    .as_ref()
                    .map(|st| st.plane_period_ns as f64 * 1e-9)
                    .unwrap_or(c.tau_s);
                // `load` has checked the maps' sizes and values.
                (Some(c.sensor_maps()), period)
            }
            AnyCalibration::Frame(_) => bail!(
                "{} is a frame-camera calibration; blink-ROI packets need a SPAD calibration",
                dir.display()
            ),
        },
    };
    if let (Some(st), Some(m)) = (&start, &maps) {
        let (w, h) = (m.width, m.height);
        if (u32::from(st.width), u32::from(st.height)) != (w, h) {
            bail!(
                "the calibration is {w}x{h} pixels but the stream's sensor is {}x{}",
                st.width,
                st.height
            );
        }
    }
    let sensor = start
        .as_ref()
        .map(|st| (st.width as usize, st.height as usize));
    if sensor.is_none() {
        eprintln!("warning: no stream-start record: pixels off the right or bottom sensor edge cannot be told apart");
    }
    let masked = rois.iter().filter(|r| r.has(rflags::MASKED)).count();
    if masked > 0 && maps.is_none() {
        eprintln!(
            "warning: {masked} ROIs contain pixels masked by the pipeline (they read 0); give --calibration to leave them out of the fit"
        );
    }
    let cfg = RecordFitConfig {
        estimator: args.estimator.estimator(),
        opts: s.opts,
        pixel_nm: s.pixel_nm,
        sensor,
        maps: maps.as_ref(),
        plane_period_s,
        hot_pixels: args.hot_pixels.mode(),
    };
    let rows: Vec<Localization> = rois
        .par_iter()
        .enumerate()
        .map(|(i, rec)| fit_record(rec, i as u64 + 1, &cfg))
        .collect();
    if let Some(path) = &args.export_tiff {
        export_tiff(path, &rois, args.export_layout, sensor)?;
    }
    let n = rows.len();
    // The sensor: the stream's, else its sidecar's, else what the ROIs reach.
    let (width, height) = match (&start, &s.sidecar) {
        (Some(st), _) => (u32::from(st.width), u32::from(st.height)),
        (None, Some(info)) => (info.width, info.height),
        (None, None) => rois.iter().fold((1, 1), |(w, h), r| {
            let side = i64::from(r.roi_size);
            (
                w.max((i64::from(r.roi_x0()) + side).clamp(1, u32::MAX as i64) as u32),
                h.max((i64::from(r.roi_y0()) + side).clamp(1, u32::MAX as i64) as u32),
            )
        }),
    };
    // Picasso's frame of a blink is its start plane: the time axis is planes.
    let last = rois.iter().map(|r| r.t_e.max(r.t_s)).max().unwrap_or(0);
    let extent = Extent {
        width,
        height,
        frames: planes.unwrap_or(0).max(last.max(0) as u64 + 1),
        data_type: "uint32".into(),
        blinks: true,
    };
    Ok((
        LocTable {
            extra_columns: vec![
                "t_start [plane]".into(),
                "t_end [plane]".into(),
                "planes".into(),
                "flags".into(),
            ],
            merged: false,
            rows,
        },
        n,
        extent,
    ))
}

pub(super) fn export_tiff(
    path: &Path,
    rois: &[BlinkRecord],
    layout: LayoutArg,
    sensor: Option<(usize, usize)>,
) -> anyhow::Result<()> {
    let pages: Vec<RoiPage> = rois
        .iter()
        .map(|r| RoiPage {
            x0: r.roi_x0(),
            y0: r.roi_y0(),
            side: r.roi_size as usize,
            counts: &r.counts,
        })
        .collect();
    let layout = match layout {
        LayoutArg::Compact => RoiLayout::Compact,
        LayoutArg::Sensor => {
            let Some((width, height)) = sensor else {
                bail!("--export-layout sensor needs the stream-start record (sensor size), which this stream lacks");
            };
            // One sensor-sized page per blink, built in memory.
            const MAX_BYTES: u64 = 2 << 30;
            let bytes = (width * height) as u64 * 4 * pages.len() as u64;
            if bytes > MAX_BYTES {
                bail!(
                    "--export-layout sensor would build {} sensor-sized pages of {width}x{height} pixels ({:.1} GiB, the limit is 2 GiB): use --export-layout compact",
                    pages.len(),
                    bytes as f64 / (1u64 << 30) as f64
                );
            }
            RoiLayout::Sensor { width, height }
        }
    };
    let (w, h, data) = smartagg_localize::export::roi_pages(&pages, layout);
    let mut out = std::io::BufWriter::new(AtomicFile::create(path)?);
    let bits16 = smartagg_io::stack::write_stack(&mut out, w, h, &data)
        .with_context(|| format!("writing {}", path.display()))?;
    out.into_inner()
        .map_err(|e| e.into_error())
        .with_context(|| format!("writing {}", path.display()))?
        .commit()?;
    if layout == RoiLayout::Compact {
        let origins = PathBuf::from(format!("{}.origins.csv", path.display()));
        let mut f = std::io::BufWriter::new(AtomicFile::create(&origins)?);
        writeln!(
            f,
            "\"page\",\"x0 [px]\",\"y0 [px]\",\"t_start [plane]\",\"t_end [plane]\",\"planes\""
        )?;
        for (i, r) in rois.iter().enumerate() {
            writeln!(
                f,
                "{},{},{},{},{},{}",
                i + 1,
                r.roi_x0(),
                r.roi_y0(),
                r.t_s,
                r.t_e,
                r.planes_summed
            )?;
        }
        f.into_inner()
            .map_err(|e| e.into_error())
            .with_context(|| format!("writing {}", origins.display()))?
            .commit()?;
        eprintln!(
            "{} ROIs written to {} ({}x{}, {}); page origins in {}",
            rois.len(),
            path.display(),
            w,
            h,
            if bits16 { "16-bit" } else { "32-bit float" },
            origins.display()
        );
    } else {
        eprintln!(
            "{} sensor-sized pages written to {}",
            rois.len(),
            path.display()
        );
    }
    Ok(())
}
