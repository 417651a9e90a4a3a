//! TIFF stacks of camera frames: a reader thread, batches of frames fitted on
//! the pool, per-pixel calibration.

use super::*;

pub(super) fn localize_tiff(args: &Args, s: &Setup) -> anyhow::Result<(LocTable, usize, Extent)> {
    let est = args.estimator.estimator();
    if args.export_tiff.is_some() {
        bail!("--export-tiff applies to blink-ROI packet input");
    }
    // ADU conversion: options, else the preset, else identity.
    let (p_off, p_epa, p_gain, p_read) = match s.preset.as_ref().map(|p| &p.camera) {
        Some(Camera::Emccd(c)) => (c.offset_adu, c.e_per_adu, c.em_gain, c.read_noise_e),
        Some(Camera::Scmos(c)) => (c.offset_adu, c.e_per_adu, 1.0, c.read_noise_e),
        _ => (0.0, 1.0, 1.0, 0.0),
    };
    let conversion = Conversion {
        offset_adu: args.offset_adu.unwrap_or(p_off),
        e_per_adu: args.e_per_adu.unwrap_or(p_epa),
        em_gain: args.em_gain.unwrap_or(p_gain),
    };
    conversion.validate()?;
    let read_noise = args.read_noise_e.unwrap_or(p_read);
    let calibration = match &args.calibration {
        None => None,
        Some(dir) => match AnyCalibration::load(dir)
            .with_context(|| format!("loading calibration {}", dir.display()))?
        {
            AnyCalibration::Frame(f) => Some(f),
            AnyCalibration::Spad(_) => bail!(
                "{} is a SPAD calibration; frames need an EMCCD or sCMOS calibration",
                dir.display()
            ),
        },
    };
    let roi = args.roi.unwrap_or_else(|| {
        let r = 2 * (3.0 * s.sigma_px).ceil() as usize + 1;
        r.clamp(7, 21)
    });
    let stack = smartagg_io::stack::open_stack(&args.input)?;
    let mut size = (0, 0);
    let mut rows = Vec::new();
    let mut frames = 0u64;
    let mut candidates = 0usize;
    let mut pipeline: Option<FramePipeline> = None;
    // A reader thread decodes batches of frames while the pool fits the
    // previous batch (decoding is a good part of a small frame's cost).
    let (tx, rx) = std::sync::mpsc::sync_channel::<anyhow::Result<Vec<_>>>(2);
    std::thread::scope(|scope| -> anyhow::Result<()> {
        scope.spawn(move || {
            let mut batch = Vec::with_capacity(FRAME_BATCH);
            let mut no = 0u64;
            for frame in stack {
                no += 1;
                match frame {
                    Ok(f) => batch.push((no, f)),
                    Err(e) => {
                        let _ = tx.send(Err(e.into()));
                        return;
                    }
                }
                if batch.len() == FRAME_BATCH
                    && tx
                        .send(Ok(std::mem::replace(
                            &mut batch,
                            Vec::with_capacity(FRAME_BATCH),
                        )))
                        .is_err()
                {
                    return;
                }
            }
            if !batch.is_empty() {
                let _ = tx.send(Ok(batch));
            }
        });
        for batch in rx {
            let mut batch = batch?;
            frames += batch.len() as u64;
            let first = &batch[0].1;
            if pipeline.is_none() {
                size = (first.width, first.height);
                let p = frame_pipeline(
                    args,
                    s,
                    est,
                    conversion,
                    read_noise,
                    roi,
                    calibration.as_ref(),
                    first,
                )?;
                let used = p.roi_for(first.width, first.height);
                if used != roi {
                    eprintln!(
                        "frames are {}x{} pixels: fitting {used}x{used} ROIs instead of {roi}x{roi}",
                        first.width, first.height
                    );
                }
                pipeline = Some(p);
            }
            let p = pipeline.as_ref().expect("set above");
            if let Some(c) = &calibration {
                for (_, frame) in batch.iter_mut() {
                    calibrate_frame(c, conversion, frame)?;
                }
            }
            candidates += localize_batch(p, &batch, &mut rows)?;
        }
        Ok(())
    })?;
    if pipeline.is_none() {
        bail!("{} holds no frames", args.input.display());
    }
    let fits = rows.len();
    eprintln!("{frames} frames, {candidates} candidates above threshold");
    let mut table = LocTable {
        extra_columns: vec![],
        merged: false,
        rows,
    };
    if let Some(d) = args.merge_nm {
        if !(d.is_finite() && d > 0.0) {
            bail!("--merge-nm must be a positive distance in nm, got {d}");
        }
        let (merged, st) = merge_consecutive(&table.rows, d, args.merge_gap);
        eprintln!(
            "merging within {d} nm over consecutive frames: {} → {} localisations ({} tracks of two or more; {} failed fits not merged)",
            st.input, st.output, st.merged_tracks, st.passed_failed
        );
        table.rows = merged;
        table.merged = true;
    }
    let extent = Extent {
        width: size.0.min(u32::MAX as usize) as u32,
        height: size.1.min(u32::MAX as usize) as u32,
        frames,
        data_type: smartagg_io::stack::numpy_data_type(&args.input),
        blinks: false,
    };
    Ok((table, fits, extent))
}

/// Frames per batch handed from the reader to the workers.
pub(super) const FRAME_BATCH: usize = 1024;

/// Per-pixel conversion of a frame with a frame calibration:
/// (ADU − offset) / (ADU per electron).
pub(super) fn calibrate_frame(
    c: &smartagg_calibration::FrameCalibration,
    conversion: Conversion,
    frame: &mut smartagg_io::stack::Frame,
) -> anyhow::Result<()> {
    if (c.width as usize, c.height as usize) != (frame.width, frame.height) {
        bail!(
            "the calibration is {}x{} pixels but the frames are {}x{}",
            c.width,
            c.height,
            frame.width,
            frame.height
        );
    }
    for (k, v) in frame.data.iter_mut().enumerate() {
        let gain = c
            .gain_adu_per_e
            .as_ref()
            .map_or(1.0 / (conversion.e_per_adu / conversion.em_gain), |g| g[k]);
        *v = (*v - c.offset_adu[k]) / gain.max(1e-12);
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
pub(super) fn frame_pipeline(
    args: &Args,
    s: &Setup,
    est: Estimator,
    conversion: Conversion,
    read_noise: f64,
    roi: usize,
    calibration: Option<&smartagg_calibration::FrameCalibration>,
    first: &smartagg_io::stack::Frame,
) -> anyhow::Result<FramePipeline> {
    let n = first.width * first.height;
    let scmos = s.opts.noise == NoiseModel::Scmos;
    let read_var = if scmos {
        Some(match calibration.and_then(|c| c.read_noise_e.as_ref()) {
            Some(m) => m.iter().map(|r| r * r).collect(),
            None => vec![read_noise * read_noise; n],
        })
    } else {
        None
    };
    let hot = calibration.map(|c| {
        let hot = c.flags.iter().map(|f| f & flags::HOT != 0).collect();
        (hot, args.hot_pixels.mode())
    });
    let p = FramePipeline {
        // With a calibration the host converts per pixel.
        conversion: if calibration.is_some() {
            Conversion::IDENTITY
        } else {
            conversion
        },
        roi_side: roi,
        threshold_factor: args.threshold,
        estimator: est,
        fit: s.opts,
        pixel_nm: s.pixel_nm,
        read_var,
        hot,
        spad_planes: args.planes,
    };
    p.validate(first.width, first.height)?;
    Ok(p)
}
