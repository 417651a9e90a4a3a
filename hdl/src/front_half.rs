//! The streaming front half: rolling count → spatial filter → threshold and
//! candidates, fed by a delay line, and its Verilog.
//!
//! [`FrontHalf`] takes the live and the delayed stream side by side (the
//! interface the DDR2 delay line, [`crate::delay_line_ddr`], feeds); [`FrontHalfBram`]
//! puts the block-RAM [`DelayLine`] in front of it (configurations whose N_max
//! planes fit block RAM). Type aliases name the generated configurations.

use crate::bundles::{CandidateWordOut, DelayedWord, PlaneWord};
use crate::candidates::Candidates;
use crate::config::{GatewareConfig, GatewareError};
use crate::delay_line::DelayLine;
use crate::hot_pixel_mask::HotPixelMask;
use crate::rolling_count::RollingCount;
use crate::spatial_filter::SpatialFilter;
use crate::stream::PackLanes;
use rust_hdl::prelude::*;

/// Rolling count, filter and candidates on P pixels per clock.
#[derive(LogicBlock)]
pub struct FrontHalf<
    const P: usize,
    const CW: usize,
    const CAW: usize,
    const VW: usize,
    const HW: usize,
    const LAW: usize,
> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start.
    pub restart: Signal<In, Bit>,
    /// T_int register (the open level of candidates).
    pub threshold: Signal<In, Bits<HW>>,
    /// T_hold register (the level of the `above` bits, ≤ T_int).
    pub threshold_hold: Signal<In, Bits<HW>>,
    /// The delay line's word: `B_t` beside `B_{t−N}`, numbered (its
    /// `drain` and `side` are the back half's).
    pub word: DelayedWord<P>,
    /// A word's above-hold bits and candidates, with its column and row
    /// (a row behind the word in: [`crate::candidates`]).
    pub out: CandidateWordOut<P>,
    count: RollingCount<P, CW, CAW>,
    filter: SpatialFilter<CW, VW, HW, LAW>,
    cands: Candidates<HW, LAW>,
    pack_above: PackLanes<P>,
    pack_cand: PackLanes<P>,
}

impl<
        const P: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
    > FrontHalf<P, CW, CAW, VW, HW, LAW>
{
    /// The front half of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &GatewareConfig) -> Result<Self, GatewareError> {
        Ok(FrontHalf {
            clock: Default::default(),
            restart: Default::default(),
            threshold: Default::default(),
            threshold_hold: Default::default(),
            word: Default::default(),
            out: Default::default(),
            count: RollingCount::new(cfg)?,
            filter: SpatialFilter::new(cfg)?,
            cands: Candidates::new(cfg)?,
            pack_above: Default::default(),
            pack_cand: Default::default(),
        })
    }
}

impl<
        const P: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
    > Logic for FrontHalf<P, CW, CAW, VW, HW, LAW>
{
    #[hdl_gen]
    fn update(&mut self) {
        clock!(self, clock, count, filter, cands);
        self.count.restart.next = self.restart.val();
        self.filter.restart.next = self.restart.val();
        self.cands.restart.next = self.restart.val();
        self.cands.threshold.next = self.threshold.val();
        self.cands.threshold_hold.next = self.threshold_hold.val();
        self.count.valid.next = self.word.valid.val();
        self.count.flush.next = self.word.flush.val();
        self.count.x.next = self.word.x.val();
        self.count.y.next = self.word.y.val();
        self.count.idx.next = self.word.idx.val();
        self.count.live.next = self.word.live.val();
        self.count.delayed.next = self.word.delayed.val();
        self.filter.valid.next = self.count.out_valid.val();
        self.filter.flush.next = self.count.out_flush.val();
        self.filter.x.next = self.count.out_x.val();
        self.filter.y.next = self.count.out_y.val();
        for i in 0..P {
            self.filter.counts[i].next = self.count.counts[i].val();
        }
        self.cands.valid.next = self.filter.out_valid.val();
        self.cands.flush.next = self.filter.out_flush.val();
        self.cands.x.next = self.filter.out_x.val();
        self.cands.y.next = self.filter.out_y.val();
        for i in 0..P {
            self.cands.filtered[i].next = self.filter.filtered[i].val();
            self.pack_above.lanes[i].next = self.cands.above[i].val();
            self.pack_cand.lanes[i].next = self.cands.candidate[i].val();
        }
        self.out.valid.next = self.cands.out_valid.val();
        self.out.flush.next = self.cands.out_flush.val();
        self.out.x.next = self.cands.out_x.val();
        self.out.y.next = self.cands.out_y.val();
        self.out.above.next = self.pack_above.word.val();
        self.out.candidate.next = self.pack_cand.word.val();
    }
}

/// The front half behind the hot-pixel mask and a block-RAM delay line: the
/// whole front half (stages 0–4) from the raw bit-plane stream to
/// above-threshold bits and candidates.
#[derive(LogicBlock)]
pub struct FrontHalfBram<
    const P: usize,
    const DAW: usize,
    const CW: usize,
    const CAW: usize,
    const VW: usize,
    const HW: usize,
    const LAW: usize,
> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: takes `n_window`, forgets all planes.
    pub restart: Signal<In, Bit>,
    /// N register (1..=N_max).
    pub n_window: Signal<In, Bits<CW>>,
    /// Mask load strobe (before the stream starts).
    pub load: Signal<In, Bit>,
    /// Mask word index.
    pub load_address: Signal<In, Bits<CAW>>,
    /// Mask word: bit i = pixel i is hot.
    pub load_data: Signal<In, Bits<P>>,
    /// T_int register (the open level of candidates).
    pub threshold: Signal<In, Bits<HW>>,
    /// T_hold register (the level of the `above` bits, ≤ T_int).
    pub threshold_hold: Signal<In, Bits<HW>>,
    /// The raw bit-plane word (`drain`: a word of a drain plane).
    pub word: PlaneWord<P>,
    /// The word's above-hold bits and candidates.
    pub out: CandidateWordOut<P>,
    mask: HotPixelMask<P, CAW>,
    delay: DelayLine<P, DAW, CW>,
    front: FrontHalf<P, CW, CAW, VW, HW, LAW>,
}

impl<
        const P: usize,
        const DAW: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
    > FrontHalfBram<P, DAW, CW, CAW, VW, HW, LAW>
{
    /// The pipeline of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &GatewareConfig) -> Result<Self, GatewareError> {
        Ok(FrontHalfBram {
            clock: Default::default(),
            restart: Default::default(),
            n_window: Default::default(),
            load: Default::default(),
            load_address: Default::default(),
            load_data: Default::default(),
            threshold: Default::default(),
            threshold_hold: Default::default(),
            word: Default::default(),
            out: Default::default(),
            mask: HotPixelMask::new(cfg)?,
            delay: DelayLine::new(cfg)?,
            front: FrontHalf::new(cfg)?,
        })
    }
}

impl<
        const P: usize,
        const DAW: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
    > Logic for FrontHalfBram<P, DAW, CW, CAW, VW, HW, LAW>
{
    #[hdl_gen]
    fn update(&mut self) {
        clock!(self, clock, mask, delay, front);
        self.mask.load.next = self.load.val();
        self.mask.load_address.next = self.load_address.val();
        self.mask.load_data.next = self.load_data.val();
        PlaneWord::<P>::link(&mut self.word, &mut self.mask.word);
        self.mask.enable.next = true;
        self.delay.restart.next = self.restart.val();
        self.front.restart.next = self.restart.val();
        self.delay.n_window.next = self.n_window.val();
        self.front.threshold.next = self.threshold.val();
        self.front.threshold_hold.next = self.threshold_hold.val();
        // (Siblings field by field: a join is a process per field in the
        // Verilog, [`crate::bundles`].)
        self.delay.word.valid.next = self.mask.out.valid.val();
        self.delay.word.sop.next = self.mask.out.sop.val();
        self.delay.word.flush.next = self.mask.out.flush.val();
        self.delay.word.drain.next = self.mask.out.drain.val();
        self.delay.word.live.next = self.mask.out.live.val();
        self.delay.side.next = self.mask.out_mask.val();
        self.front.word.valid.next = self.delay.out.valid.val();
        self.front.word.flush.next = self.delay.out.flush.val();
        self.front.word.drain.next = self.delay.out.drain.val();
        self.front.word.x.next = self.delay.out.x.val();
        self.front.word.y.next = self.delay.out.y.val();
        self.front.word.idx.next = self.delay.out.idx.val();
        self.front.word.live.next = self.delay.out.live.val();
        self.front.word.delayed.next = self.delay.out.delayed.val();
        self.front.word.side.next = self.delay.out.side.val();
        CandidateWordOut::<P>::link(&mut self.out, &mut self.front.out);
    }
}

/// The small test configuration: 16×6 pixels, P = 4, k1 = [1 4 6 4 1]
/// (a = 4), N_max = 7.
pub fn test_config() -> GatewareConfig {
    GatewareConfig {
        width: 16,
        height: 6,
        pixels_per_clock: 4,
        n_max: 7,
        kernel: vec![1, 4, 6, 4, 1],
        kernel_shift: 4,
        dsp_multipliers: 0,
        sized_for: None,
    }
}

/// [`FrontHalfBram`] of [`test_config`].
pub type TestFrontHalf = FrontHalfBram<4, 8, 3, 5, 7, 11, 2>;

/// The SPCImager at 150× (320×240, P = 16, N_max = 128 ≥ N ≈ 108): k = 9,
/// a = 8, k1 the pixel-integrated Gaussian of σ = 1.514 px scaled to 2^8
/// (computed by `examples/resources.rs`; the model's kernel module will
/// define the official rounding).
pub fn spcimager150_config() -> GatewareConfig {
    GatewareConfig {
        width: 320,
        height: 240,
        pixels_per_clock: 16,
        n_max: 128,
        kernel: vec![2, 10, 29, 54, 66, 54, 29, 10, 2],
        kernel_shift: 8,
        dsp_multipliers: crate::device::device_for(smartagg_model::params::PresetName::Spcimager)
            .dsp48a1 as usize,
        sized_for: None,
    }
}

/// [`FrontHalf`] for the SPCImager at 150× (320×240, P = 16, N_max = 128,
/// k = 9, a = 8): the delay line (128 planes, 9.8 Mbit) goes to DDR2.
pub type Spcimager150FrontHalf = FrontHalf<16, 8, 13, 16, 24, 5>;

/// Verilog of a block (top module `top`), after rust-hdl's design checks,
/// with Verilator's scheduling hints ([`crate::schedule`]).
pub fn verilog<B: Block>(mut block: B) -> String {
    block.connect_all();
    crate::schedule::isolate_false_loops(&generate_verilog(&block)).0
}

/// Verilog of the test configuration's whole front half.
pub fn test_front_half_verilog() -> Result<String, GatewareError> {
    Ok(verilog(TestFrontHalf::new(&test_config())?))
}
