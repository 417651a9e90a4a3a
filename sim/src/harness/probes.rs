//! The diagnosis of a mismatch: the stages with probes, the debug build's
//! probe ports compared with the model's stages plane by plane as words
//! come out, and the input shadow and VCD window the hosts share.

use super::{Case, Cosim, HarnessError};
use crate::verilator::Model;
use smartagg_model::hot_pixel_mask::HotPixelMask;
use smartagg_model::plane::BitPlane;
use std::collections::{BTreeMap, VecDeque};
use std::path::{Path, PathBuf};

/// A pipeline stage with a probe.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Stage {
    /// Stage 0 + 1a: the masked live word `B_t` out of the delay line.
    MaskAndDelayLive,
    /// Stage 1a: `B_{t−N}` out of the delay line.
    DelayLine,
    /// Stage 1: rolling count S.
    RollingCount,
    /// Stage 2: spatial filter H.
    SpatialFilter,
    /// Stage 3: threshold `H ≥ T_hold` (the tracker's on/off bits).
    Threshold,
    /// Stage 4: candidates (3×3 local maxima).
    Candidates,
    /// Stages 5–7: tracker, ROI aggregator, packetiser, output FIFO.
    BackHalf,
}

impl Stage {
    /// The stage's name in the paper's and the model's words.
    pub fn name(self) -> &'static str {
        match self {
            Stage::MaskAndDelayLive => "hot-pixel mask (live bit-plane)",
            Stage::DelayLine => "delay line (B_{t-N})",
            Stage::RollingCount => "rolling count",
            Stage::SpatialFilter => "spatial filter",
            Stage::Threshold => "threshold",
            Stage::Candidates => "candidates",
            Stage::BackHalf => "back half (blink tracker, ROI aggregator, packetiser)",
        }
    }
}

/// The first difference of one stage.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StageMismatch {
    /// Which stage.
    pub stage: Stage,
    /// Bit-plane.
    pub plane: u64,
    /// Word within the plane (P pixels, raster order).
    pub word: usize,
    /// Clock of the run at which it came out.
    pub cycle: u64,
    /// Lane values, gateware.
    pub got: Vec<u64>,
    /// Lane values, model.
    pub want: Vec<u64>,
}

/// The first mismatch of a case, named.
#[derive(Debug, Clone)]
pub struct Mismatch {
    /// The first stage that differs.
    pub stage: Stage,
    /// The first bit-plane at which it differs.
    pub plane: u64,
    /// What differs.
    pub detail: String,
    /// VCD of the clocks around it, if written.
    pub vcd: Option<PathBuf>,
}

impl std::fmt::Display for Mismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "first mismatch in stage `{}` at bit-plane {}: {}",
            self.stage.name(),
            self.plane,
            self.detail
        )?;
        if let Some(v) = &self.vcd {
            write!(f, " (VCD: {})", v.display())?;
        }
        Ok(())
    }
}

/// Expected stage outputs of one plane (model).
struct ExpPlane {
    live: BitPlane,
    delayed: BitPlane,
    counts: Vec<u32>,
    filtered: Vec<u32>,
    cand: Vec<bool>,
}

/// The model's stages, advanced plane by plane as the probes need them.
struct Expect {
    model: smartagg_model::pipeline::Pipeline,
    mask: Option<HotPixelMask>,
    planes: Vec<BitPlane>,
    n: u64,
    cache: BTreeMap<u64, ExpPlane>,
    masked: VecDeque<BitPlane>,
    next: u64,
}

impl Expect {
    fn get(&mut self, t: u64) -> Option<&ExpPlane> {
        if t as usize >= self.planes.len() {
            return None;
        }
        while self.next <= t {
            let i = self.next as usize;
            let live = match &self.mask {
                Some(m) => m.apply(&self.planes[i]),
                None => self.planes[i].clone(),
            };
            let (w, h) = (live.width(), live.height());
            self.masked.push_back(live.clone());
            let delayed = if self.masked.len() as u64 > self.n {
                self.masked
                    .pop_front()
                    .unwrap_or_else(|| BitPlane::zeros(w, h))
            } else {
                BitPlane::zeros(w, h)
            };
            self.model.push_plane(&self.planes[i]).ok()?;
            let mut cand = vec![false; w * h];
            for c in self.model.candidates() {
                cand[c.y as usize * w + c.x as usize] = true;
            }
            self.cache.insert(
                self.next,
                ExpPlane {
                    live,
                    delayed,
                    counts: self.model.counts().to_vec(),
                    filtered: self.model.filtered().to_vec(),
                    cand,
                },
            );
            self.next += 1;
            // Keep a few planes: the stages lag each other by less than one.
            while self.cache.len() > 4 {
                let k = *self.cache.keys().next().unwrap_or(&0);
                self.cache.remove(&k);
            }
        }
        self.cache.get(&t)
    }
}

/// Probe ports of one stage and how many words it has put out.
struct StageProbe {
    stage: Stage,
    valid: usize,
    flush: usize,
    data: usize,
    words: u64,
    first: Option<StageMismatch>,
}

/// Stage probes of a debug build, compared with the model as words come out.
pub(super) struct Probes {
    stages: Vec<StageProbe>,
    expect: Expect,
    threshold: u32,
    wpp: usize,
    width: usize,
    cw: usize,
    hw: usize,
}

impl Probes {
    pub(super) fn new(m: &Model, cosim: &Cosim, case: &Case) -> Result<Probes, HarnessError> {
        let b = m.build();
        let port = |n: &str| b.port(n).map_err(|e| HarnessError::Design(e.into()));
        let mut stages = Vec::new();
        for (stage, tag, data) in [
            (Stage::MaskAndDelayLive, "d", "d_live"),
            (Stage::DelayLine, "d", "d_delayed"),
            (Stage::RollingCount, "c", "c_counts"),
            (Stage::SpatialFilter, "f", "f_h"),
            (Stage::Threshold, "k", "k_above"),
            (Stage::Candidates, "k", "k_cand"),
        ] {
            stages.push(StageProbe {
                stage,
                valid: port(&format!("{tag}_valid"))?,
                flush: port(&format!("{tag}_flush"))?,
                data: port(data)?,
                words: 0,
                first: None,
            });
        }
        let cfg = cosim.model_config(case)?;
        let f = cosim.spec.front()?;
        Ok(Probes {
            stages,
            expect: Expect {
                model: smartagg_model::pipeline::Pipeline::new(cfg.clone())
                    .map_err(|e| HarnessError::Model(e.to_string()))?,
                mask: cfg.hot_mask.clone(),
                planes: case.planes.clone(),
                n: case.n as u64,
                cache: BTreeMap::new(),
                masked: VecDeque::new(),
                next: 0,
            },
            threshold: case.hold(),
            wpp: f.words_per_plane(),
            width: f.width,
            cw: f.count_bits(),
            hw: f.filtered_bits(),
        })
    }

    /// Samples every probe for this clock (before the edge).
    pub(super) fn sample(&mut self, m: &mut Model) {
        let p = crate::designs::P;
        for s in &mut self.stages {
            if s.first.is_some() {
                continue;
            }
            if m.get(s.valid) == 0 || m.get(s.flush) != 0 {
                continue;
            }
            let t = s.words / self.wpp as u64;
            let idx = (s.words % self.wpp as u64) as usize;
            s.words += 1;
            let words = m.get_words(s.data);
            let Some(e) = self.expect.get(t) else {
                continue;
            };
            let lane_bits = match s.stage {
                Stage::RollingCount => self.cw,
                Stage::SpatialFilter => self.hw,
                _ => 1,
            };
            let got: Vec<u64> = (0..p)
                .map(|i| extract(&words, i * lane_bits, lane_bits))
                .collect();
            let want: Vec<u64> = (0..p)
                .map(|i| {
                    let px = idx * p + i;
                    let (x, y) = (px % self.width, px / self.width);
                    match s.stage {
                        Stage::MaskAndDelayLive => e.live.get(x, y) as u64,
                        Stage::DelayLine => e.delayed.get(x, y) as u64,
                        Stage::RollingCount => e.counts[px] as u64,
                        Stage::SpatialFilter => e.filtered[px] as u64,
                        Stage::Threshold => (e.filtered[px] >= self.threshold) as u64,
                        Stage::Candidates => e.cand[px] as u64,
                        Stage::BackHalf => 0,
                    }
                })
                .collect();
            if got != want {
                s.first = Some(StageMismatch {
                    stage: s.stage,
                    plane: t,
                    word: idx,
                    cycle: m.cycles,
                    got,
                    want,
                });
            }
        }
    }

    pub(super) fn mismatches(&self) -> Vec<StageMismatch> {
        self.stages.iter().filter_map(|s| s.first.clone()).collect()
    }
}

/// Bits `at .. at + n` of little-endian 32-bit words.
fn extract(words: &[u32], at: usize, n: usize) -> u64 {
    let mut v = 0u64;
    for k in 0..n {
        let b = at + k;
        if (words[b / 32] >> (b % 32)) & 1 != 0 {
            v |= 1 << k;
        }
    }
    v
}

/// Input shadow: sets a port only when its value changes.
pub(super) struct Shadow {
    pub(super) vals: Vec<Option<u64>>,
}

impl Shadow {
    pub(super) fn set(&mut self, m: &mut Model, i: usize, v: u64) {
        if self.vals[i] != Some(v) {
            m.set(i, v);
            self.vals[i] = Some(v);
        }
    }
}

/// The VCD window of a run.
pub(super) struct Vcd {
    path: PathBuf,
    from: u64,
    to: u64,
    pub(super) open: bool,
}

impl Vcd {
    pub(super) fn step(&mut self, m: &mut Model) {
        if !self.open && m.cycles >= self.from && m.cycles < self.to {
            self.open = m.trace_open(&self.path);
        } else if self.open && m.cycles >= self.to {
            m.trace_close();
            self.open = false;
        }
    }
}

pub(super) fn vcd_of(vcd: Option<(&Path, u64, u64)>) -> Option<Vcd> {
    vcd.map(|(p, from, to)| Vcd {
        path: p.to_path_buf(),
        from,
        to,
        open: false,
    })
}
