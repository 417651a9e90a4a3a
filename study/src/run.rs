//! Running a study: the work items of a shard, in parallel on all cores.

use crate::acquisition::Setup;
use crate::error::StudyError;
use crate::item::{run_item, ItemResult};
use crate::spec::{Plan, Shard};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The setups (statistics, pipeline configuration) of every configuration.
pub fn setups(plan: &Plan) -> Result<Vec<Setup>, StudyError> {
    plan.configs
        .iter()
        .map(|c| {
            Setup::new(c.preset, c.objective)?
                .with_pipeline(plan.options.l_min, plan.options.r_assoc)?
                .with_sensor(plan.options.calibration.as_ref())
        })
        .collect()
}

/// The canonical items of `plan` that belong to `shard`.
pub fn shard_items(plan: &Plan, shard: Shard) -> Vec<(usize, usize)> {
    plan.items()
        .into_iter()
        .enumerate()
        .filter(|(k, _)| shard.owns(*k))
        .map(|(_, it)| it)
        .collect()
}

/// Runs the items of `shard` on rayon's pool (all cores unless the caller
/// set up a smaller pool), calling `progress(done, total)` after each item.
/// Results come back in canonical order whatever the scheduling, and each
/// item depends only on (seed, point, block), so any split into shards
/// gives the same numbers.
pub fn run(
    plan: &Plan,
    shard: Shard,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Vec<ItemResult>, StudyError> {
    if let Some(cal) = &plan.options.calibration {
        if cal.sensor.is_none() {
            return Err(crate::StudyError::Option {
                name: "calibration",
                why: format!("{}: the maps are not loaded, cannot simulate", cal.id),
            });
        }
    }
    let setups = setups(plan)?;
    let items = shard_items(plan, shard);
    let total = items.len();
    let done = AtomicUsize::new(0);
    progress(0, total);
    let mut results: Vec<ItemResult> = items
        .par_iter()
        .map(|&(p, b)| {
            let r = run_item(plan, &setups, p, b);
            progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            r
        })
        .collect::<Result<_, _>>()?;
    results.sort_by_key(|r| (r.point, r.block));
    Ok(results)
}

/// What a run wrote.
#[derive(Debug, Clone, Default)]
pub struct Written {
    /// Files written.
    pub files: Vec<std::path::PathBuf>,
    /// Outputs that could not be produced (a plot without a font, say).
    pub warnings: Vec<String>,
}

/// Runs `shard` of `plan` and writes its raw results to `out`; a whole run
/// (`shard` = 1/1) also writes the final tables, plot and summary.
pub fn run_to_dir(
    plan: &Plan,
    shard: Shard,
    out: &std::path::Path,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Written, StudyError> {
    let items = run(plan, shard, progress)?;
    crate::store::write_raw(out, plan, shard, &items)?;
    let mut w = Written {
        files: [
            "manifest.json",
            "blinks.csv",
            "items.csv",
            "item-timing.csv",
        ]
        .iter()
        .map(|f| out.join(f))
        .collect(),
        warnings: Vec::new(),
    };
    if shard.count == 1 {
        let prov = format!("Computed in one run (`smartagg study {}`).", plan.study);
        let (files, warnings) = crate::report::finalize(out, plan, &items, &prov)?;
        w.files.extend(files);
        w.warnings = warnings;
    }
    Ok(w)
}

/// Merges shard directories into `out`: checks they form one complete
/// study, writes the merged raw files and the final outputs.
pub fn merge_to_dir(
    dirs: &[std::path::PathBuf],
    out: &std::path::Path,
) -> Result<(Plan, Written), StudyError> {
    let (plan, items) = crate::store::merge_dirs(dirs)?;
    crate::store::write_raw(out, &plan, Shard::ALL, &items)?;
    let prov = format!(
        "Merged from {} shard director{} (`smartagg study merge`).",
        dirs.len(),
        if dirs.len() == 1 { "y" } else { "ies" }
    );
    let (mut files, warnings) = crate::report::finalize(out, &plan, &items, &prov)?;
    files.extend(
        [
            "manifest.json",
            "blinks.csv",
            "items.csv",
            "item-timing.csv",
        ]
        .iter()
        .map(|f| out.join(f)),
    );
    Ok((plan, Written { files, warnings }))
}
