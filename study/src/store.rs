//! The raw results of a run or shard on disk, and merging shards.
//!
//! A run (or shard) writes to its directory:
//!
//! * `manifest.json` — study, options, shard and the items it holds;
//! * `blinks.csv` — `point,block,blink,scheme,matches,sse_nm2,sum_dx_nm,sum_dy_nm`,
//!   one row per blink and scheme;
//! * `items.csv` — `point,block,scheme,detections,false_pos,failed_fits`;
//! * `item-timing.csv` — `point,block,stage,count,seconds` (wall time; the
//!   only file that differs between two runs of the same study).
//!
//! Floating-point values are written with Rust's shortest round-trip
//! formatting, so reading them back gives the same bits and a merge of
//! shards summarises exactly what the unsharded run does.

use crate::error::StudyError;
use crate::item::{ItemResult, Timing};
use crate::matching::{BlinkOutcome, SchemeOutcome};
use crate::spec::{Plan, Shard, StudyName, StudyOptions};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Version of the raw file layout.
pub const FORMAT: u32 = 1;

/// What a run directory holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// [`FORMAT`].
    pub format: u32,
    /// The study.
    pub study: StudyName,
    /// Its options.
    pub options: StudyOptions,
    /// The shard this directory holds (`1/1` for a whole run or a merge).
    pub shard: Shard,
    /// The items, `(point, block)`.
    pub items: Vec<(usize, usize)>,
}

fn write(path: &Path, text: &str) -> Result<(), StudyError> {
    crate::experiment::common::write_text(path, text)
}

fn read(path: &Path) -> Result<String, StudyError> {
    std::fs::read_to_string(path).map_err(|e| StudyError::io(path, e))
}

/// Writes the raw files of `items` to `dir` (created if needed).
pub fn write_raw(
    dir: &Path,
    plan: &Plan,
    shard: Shard,
    items: &[ItemResult],
) -> Result<(), StudyError> {
    std::fs::create_dir_all(dir).map_err(|e| StudyError::io(dir, e))?;
    let manifest = Manifest {
        format: FORMAT,
        study: plan.study,
        options: plan.options.clone(),
        shard,
        items: items.iter().map(|i| (i.point, i.block)).collect(),
    };
    let json = serde_json::to_string_pretty(&manifest).map_err(|e| StudyError::Parse {
        path: dir.join("manifest.json"),
        line: 0,
        why: e.to_string(),
    })?;
    write(&dir.join("manifest.json"), &(json + "\n"))?;
    let mut blinks = String::from("point,block,blink,scheme,matches,sse_nm2,sum_dx_nm,sum_dy_nm\n");
    let mut its = String::from("point,block,scheme,detections,false_pos,failed_fits\n");
    let mut timing = String::from("point,block,stage,count,seconds\n");
    for it in items {
        for (s, o) in it.outcomes.iter().enumerate() {
            let id = &plan.schemes[s].id;
            for (k, b) in o.blinks.iter().enumerate() {
                let _ = writeln!(
                    blinks,
                    "{},{},{},{},{},{},{},{}",
                    it.point, it.block, k, id, b.matches, b.sse_nm2, b.sum_dx_nm, b.sum_dy_nm
                );
            }
            let _ = writeln!(
                its,
                "{},{},{},{},{},{}",
                it.point, it.block, id, o.detections, o.false_pos, o.failed_fits
            );
        }
        for t in &it.timings {
            let _ = writeln!(
                timing,
                "{},{},{},{},{}",
                it.point, it.block, t.stage, t.count, t.seconds
            );
        }
    }
    write(&dir.join("blinks.csv"), &blinks)?;
    write(&dir.join("items.csv"), &its)?;
    write(&dir.join("item-timing.csv"), &timing)?;
    Ok(())
}

/// Rows of a CSV file after its header, split on commas, with line numbers.
fn rows<'a>(
    path: &Path,
    text: &'a str,
    header: &str,
) -> Result<Vec<(usize, Vec<&'a str>)>, StudyError> {
    let mut lines = text.lines();
    let first = lines.next().unwrap_or("");
    if first != header {
        return Err(StudyError::Parse {
            path: path.to_path_buf(),
            line: 1,
            why: format!("expected header `{header}`, found `{first}`"),
        });
    }
    let n = header.split(',').count();
    let mut out = Vec::new();
    for (i, l) in lines.enumerate() {
        if l.is_empty() {
            continue;
        }
        let f: Vec<&str> = l.split(',').collect();
        if f.len() != n {
            return Err(StudyError::Parse {
                path: path.to_path_buf(),
                line: i + 2,
                why: format!("{} columns, expected {n}", f.len()),
            });
        }
        out.push((i + 2, f));
    }
    Ok(out)
}

fn field<T: std::str::FromStr>(
    path: &Path,
    line: usize,
    f: &[&str],
    i: usize,
    name: &str,
) -> Result<T, StudyError> {
    let bad = || StudyError::Parse {
        path: path.to_path_buf(),
        line,
        why: format!("bad {name} `{}`", f.get(i).copied().unwrap_or("")),
    };
    f.get(i).ok_or_else(bad)?.parse().map_err(|_| bad())
}

fn finite(path: &Path, line: usize, v: f64) -> Result<f64, StudyError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(StudyError::Parse {
            path: path.to_path_buf(),
            line,
            why: format!("non-finite value {v}"),
        })
    }
}

fn non_negative(path: &Path, line: usize, v: f64) -> Result<f64, StudyError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(StudyError::Parse {
            path: path.to_path_buf(),
            line,
            why: format!("a sum of squares must be finite and not negative, found {v}"),
        })
    }
}

/// Reads a run or shard directory back: its manifest and items.
pub fn read_raw(dir: &Path) -> Result<(Manifest, Vec<ItemResult>), StudyError> {
    let mpath = dir.join("manifest.json");
    let manifest: Manifest =
        serde_json::from_str(&read(&mpath)?).map_err(|e| StudyError::Parse {
            path: mpath.clone(),
            line: e.line(),
            why: e.to_string(),
        })?;
    if manifest.format != FORMAT {
        return Err(StudyError::Parse {
            path: mpath,
            line: 0,
            why: format!(
                "raw format {} (this smartagg reads {FORMAT})",
                manifest.format
            ),
        });
    }
    let plan = Plan::new(manifest.study, manifest.options.clone())?;
    let mut map: BTreeMap<(usize, usize), ItemResult> = BTreeMap::new();
    for &(p, b) in &manifest.items {
        if p >= plan.points.len() || b >= plan.blocks() {
            return Err(StudyError::Parse {
                path: mpath.clone(),
                line: 0,
                why: format!("item ({p}, {b}) is not part of the study"),
            });
        }
        let n = plan.blinks_in_block(b);
        map.insert(
            (p, b),
            ItemResult {
                point: p,
                block: b,
                outcomes: vec![
                    SchemeOutcome {
                        blinks: vec![BlinkOutcome::default(); n],
                        ..Default::default()
                    };
                    plan.schemes.len()
                ],
                timings: Vec::new(),
            },
        );
    }
    let scheme = |path: &Path, line: usize, id: &str| {
        plan.scheme(id).ok_or_else(|| StudyError::Parse {
            path: path.to_path_buf(),
            line,
            why: format!("unknown scheme `{id}`"),
        })
    };
    let check = |map: &BTreeMap<(usize, usize), ItemResult>,
                 path: &Path,
                 line: usize,
                 p: usize,
                 b: usize|
     -> Result<(), StudyError> {
        if map.contains_key(&(p, b)) {
            Ok(())
        } else {
            Err(StudyError::Parse {
                path: path.to_path_buf(),
                line,
                why: format!("item ({p}, {b}) is not in the manifest"),
            })
        }
    };
    let bpath = dir.join("blinks.csv");
    let text = read(&bpath)?;
    let mut seen_blinks = 0usize;
    for (line, f) in rows(
        &bpath,
        &text,
        "point,block,blink,scheme,matches,sse_nm2,sum_dx_nm,sum_dy_nm",
    )? {
        let p: usize = field(&bpath, line, &f, 0, "point")?;
        let b: usize = field(&bpath, line, &f, 1, "block")?;
        let k: usize = field(&bpath, line, &f, 2, "blink")?;
        let s = scheme(&bpath, line, f[3])?;
        check(&map, &bpath, line, p, b)?;
        let item = map.get_mut(&(p, b)).expect("checked above");
        let slot = item.outcomes[s]
            .blinks
            .get_mut(k)
            .ok_or_else(|| StudyError::Parse {
                path: bpath.clone(),
                line,
                why: format!("blink {k} beyond the block's blinks"),
            })?;
        *slot = BlinkOutcome {
            matches: field(&bpath, line, &f, 4, "matches")?,
            sse_nm2: non_negative(&bpath, line, field(&bpath, line, &f, 5, "sse_nm2")?)?,
            sum_dx_nm: finite(&bpath, line, field(&bpath, line, &f, 6, "sum_dx_nm")?)?,
            sum_dy_nm: finite(&bpath, line, field(&bpath, line, &f, 7, "sum_dy_nm")?)?,
        };
        seen_blinks += 1;
    }
    let expected: usize = manifest
        .items
        .iter()
        .map(|&(_, b)| plan.blinks_in_block(b) * plan.schemes.len())
        .sum();
    if seen_blinks != expected {
        return Err(StudyError::Parse {
            path: bpath,
            line: 0,
            why: format!("{seen_blinks} rows, the manifest's items need {expected}"),
        });
    }
    let ipath = dir.join("items.csv");
    let text = read(&ipath)?;
    for (line, f) in rows(
        &ipath,
        &text,
        "point,block,scheme,detections,false_pos,failed_fits",
    )? {
        let p: usize = field(&ipath, line, &f, 0, "point")?;
        let b: usize = field(&ipath, line, &f, 1, "block")?;
        let s = scheme(&ipath, line, f[2])?;
        check(&map, &ipath, line, p, b)?;
        let o = &mut map.get_mut(&(p, b)).expect("checked").outcomes[s];
        o.detections = field(&ipath, line, &f, 3, "detections")?;
        o.false_pos = field(&ipath, line, &f, 4, "false_pos")?;
        o.failed_fits = field(&ipath, line, &f, 5, "failed_fits")?;
    }
    let tpath = dir.join("item-timing.csv");
    let text = read(&tpath)?;
    for (line, f) in rows(&tpath, &text, "point,block,stage,count,seconds")? {
        let p: usize = field(&tpath, line, &f, 0, "point")?;
        let b: usize = field(&tpath, line, &f, 1, "block")?;
        check(&map, &tpath, line, p, b)?;
        let t = Timing {
            stage: f.get(2).copied().unwrap_or_default().to_string(),
            count: field(&tpath, line, &f, 3, "count")?,
            seconds: finite(&tpath, line, field(&tpath, line, &f, 4, "seconds")?)?,
        };
        map.get_mut(&(p, b)).expect("checked").timings.push(t);
    }
    Ok((manifest, map.into_values().collect()))
}

/// Reads shard directories and checks that they belong to one study and
/// cover every item exactly once. Returns the plan and all items.
pub fn merge_dirs(dirs: &[PathBuf]) -> Result<(Plan, Vec<ItemResult>), StudyError> {
    if dirs.is_empty() {
        return Err(StudyError::Merge("no shard directory given".into()));
    }
    let mut first: Option<Manifest> = None;
    let mut all: BTreeMap<(usize, usize), (ItemResult, PathBuf)> = BTreeMap::new();
    for d in dirs {
        let (m, items) = read_raw(d)?;
        if let Some(f) = &first {
            if f.study != m.study || f.options != m.options {
                return Err(StudyError::Merge(format!(
                    "{} is a different run ({} {:?}) from {} ({} {:?})",
                    d.display(),
                    m.study,
                    m.options,
                    dirs[0].display(),
                    f.study,
                    f.options
                )));
            }
        } else {
            first = Some(m.clone());
        }
        for it in items {
            let key = (it.point, it.block);
            if let Some((_, other)) = all.get(&key) {
                return Err(StudyError::Merge(format!(
                    "item (point {}, block {}) is in both {} and {}",
                    key.0,
                    key.1,
                    other.display(),
                    d.display()
                )));
            }
            all.insert(key, (it, d.clone()));
        }
    }
    let m = first.expect("at least one directory");
    let plan = Plan::new(m.study, m.options)?;
    let missing: Vec<(usize, usize)> = plan
        .items()
        .into_iter()
        .filter(|k| !all.contains_key(k))
        .collect();
    if !missing.is_empty() {
        return Err(StudyError::Merge(format!(
            "{} of {} items missing (first: point {}, block {}); is a shard missing?",
            missing.len(),
            plan.items().len(),
            missing[0].0,
            missing[0].1
        )));
    }
    Ok((plan, all.into_values().map(|(it, _)| it).collect()))
}
