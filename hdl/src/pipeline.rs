//! The whole pipeline, gateware twin of `model/src/pipeline.rs`: stream
//! control, hot-pixel mask, delay line, front half (rolling count, filter,
//! threshold, candidates), back half (blink tracker, ROI aggregator,
//! packetiser) and the output FIFO. With no back-pressure it produces the
//! byte stream of `model::pipeline::run` + `model::packetiser::encode_stream`.
//!
//! **Stream start** ([`StreamControl`]): START checks the registers as the
//! model's `PipelineConfig::validate` does (1 ≤ N ≤ N_max, T_int ≥ 1,
//! 1 ≤ T_hold ≤ T_int, END_TRIM ≤ N − 1, L_min ≥ 1,
//! max(L_min, N) ≤ L_max ≤ L_max,max; otherwise `config_error` and nothing
//! starts; the check is a register of the START clock's values and decides
//! a clock later), latches N, T_int, T_hold, END_TRIM, L_min, L_max, the
//! plane period, the masked-pixel count and MASK_ENABLE, restarts every
//! block (the tracker then pushes StreamStart,
//! sequence 0) and waits for the first `sop`. The front half compares H with
//! `min(T_int, 2^HW − 1)` (candidates) and `min(T_hold, 2^HW − 1)` (the
//! tracker's on/off bits), which decide the same since
//! `H ≤ N_max·2^(2a) < 2^HW − 1`.
//!
//! **Stream end**: STOP takes effect at the next plane boundary (a partial
//! plane is completed first). The control then sends N *drain planes* —
//! stored in the delay line, so that `B_{p−N} … B_{p−1}` come out for the
//! sums still open, as the model's `Pipeline::finish` reads them from its
//! delay line — and one flush plane that pushes the last rows out of the
//! row-lagged stages; the tracker truncates the live tracks after plane
//! p − 1, completes their sums (and those of segments that dropped and
//! wait for their last planes) during the drain planes, emits the
//! remaining segments and StreamEnd. `ended` rises when the last byte is in
//! the output FIFO. With p = 0 planes nothing is drained.
//!
//! **Throughput.** Every stage takes one word per clock; the back half needs
//! one clock per word with an above-threshold pixel, one per extra candidate
//! in a word, one after each opening that another candidate follows (at most
//! M a plane), M + 5 per plane and one per ROI row per slot; the sensor's
//! 47.6 % duty cycle at P = 16 (see the crate docs) leaves that headroom.
//! A source that can wait (the replay) is paced by `ready` instead: the
//! stream accepts words and the back half has room (the tracker's FIFO and
//! the ROI ring each keep a margin for the words already on their way), so
//! it may send a word on every clock and a dense scene only slows it down.
//! Every place where a burst could exceed a buffer has a sticky flag
//! (`fault`): never a silent loss.

use crate::back_half::BackHalf;
use crate::bundles::{McbPort, RuntimeRegisters};
use crate::config::{BackHalfConfig, GatewareConfig, GatewareError};
use crate::delay_line::DelayLine;
use crate::delay_line_ddr::DelayLineDdr;
use crate::front_half::FrontHalf;
use crate::hot_pixel_mask::HotPixelMask;
use crate::stream_control::StreamControl;
use rust_hdl::prelude::*;

/// Declares a whole pipeline ([`Pipeline`], [`PipelineDdr`]) around a delay
/// line: one text for both, since the XEM6310 core reads either's ports by
/// name ([`crate::xem6310_core`]). What differs is named: the delay line's
/// type and its address-width parameter (`$dw`), the MCB port's signal that
/// START also waits for (`gate`), the MCB port linked to the delay line's
/// (`mcb_link`, with the signal `mem_ready` follows) or left idle (each
/// output's constant), and the delay line's faults. The update's statements are
/// written here, not passed in: `self` in a macro's argument is not the
/// `self` of a method the macro writes.
macro_rules! pipeline_block {
    (
        $(#[$attr:meta])*
        $name:ident, $dw:ident,
        delay: { $($delay:tt)* },
        fault_doc: $fault_doc:literal,
        mem_ready_doc: $mem_ready_doc:literal,
        mcb_doc: $mcb_doc:literal,
        gate: [$($gate:ident),*],
        mcb_link: [$($mcb_link:ident)?],
        ready_from: [$($ready_from:ident)?],
        faults: [$($fault:ident),*],
        idle: [$($idle:ident = { $($idle_value:tt)* }),*],
        mcb_idle: [$($mcb_idle:ident = { $($mcb_idle_value:tt)* }),*]
    ) => {
$(#[$attr])*
#[derive(LogicBlock)]
pub struct $name<
    const P: usize,
    const $dw: usize,
    const CW: usize,
    const CAW: usize,
    const VW: usize,
    const HW: usize,
    const LAW: usize,
    const RAW: usize,
    const RCW: usize,
    const CAW2: usize,
    const BW: usize,
    const QAW: usize,
    const QW: usize,
    const PW: usize,
    const TW: usize,
    const TAW: usize,
    const OAW: usize,
> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// START.
    pub start: Signal<In, Bit>,
    /// STOP.
    pub stop: Signal<In, Bit>,
    /// RESET.
    pub reset: Signal<In, Bit>,
    /// The runtime registers as the host wrote them (checked and latched
    /// by stream control at START).
    pub regs: RuntimeRegisters,
    /// Mask load strobe (while stopped).
    pub load: Signal<In, Bit>,
    /// Mask word index.
    pub load_address: Signal<In, Bits<CAW>>,
    /// Mask word.
    pub load_data: Signal<In, Bits<P>>,
    /// A source word.
    pub in_valid: Signal<In, Bit>,
    /// First word of a plane.
    pub in_sop: Signal<In, Bit>,
    /// Its pixels (pixel i in bit i).
    pub in_live: Signal<In, Bits<P>>,
    /// A packet byte is available.
    pub out_valid: Signal<Out, Bit>,
    /// The byte.
    pub out_data: Signal<Out, Bits<8>>,
    /// Take it.
    pub out_pop: Signal<In, Bit>,
    /// Bytes waiting.
    pub out_count: Signal<Out, Bits<16>>,
    /// A stream is running.
    pub running: Signal<Out, Bit>,
    /// Source words are taken now.
    pub accepting: Signal<Out, Bit>,
    /// Source words are taken now and the back half has room for them
    /// ([`BackHalf`]'s `room`): a source that can wait, such as the replay,
    /// sends only while this is high and may then send a word every clock.
    pub ready: Signal<Out, Bit>,
    /// The stream has ended.
    pub ended: Signal<Out, Bit>,
    /// START refused: register out of range.
    pub config_error: Signal<Out, Bit>,
    /// `sop` inside a plane.
    pub framing_error: Signal<Out, Bit>,
    /// Records were lost (Overflow records tell how many).
    pub overflowed: Signal<Out, Bit>,
    #[doc = $fault_doc]
    pub fault: Signal<Out, Bit>,
    /// The mask load port is open: no stream is starting or running. Loads
    /// while it is low are ignored, so the mask a stream uses is the one
    /// loaded before its START.
    pub mask_loadable: Signal<Out, Bit>,
    #[doc = $mem_ready_doc]
    pub mem_ready: Signal<Out, Bit>,
    #[doc = $mcb_doc]
    pub mcb: McbPort,
    control: StreamControl<P, CW, HW>,
    mask: HotPixelMask<P, CAW>,
    delay: $($delay)*,
    front: FrontHalf<P, CW, CAW, VW, HW, LAW>,
    back: BackHalf<P, CW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>,
}

impl<
        const P: usize,
        const $dw: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
        const RAW: usize,
        const RCW: usize,
        const CAW2: usize,
        const BW: usize,
        const QAW: usize,
        const QW: usize,
        const PW: usize,
        const TW: usize,
        const TAW: usize,
        const OAW: usize,
    > $name<P, $dw, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>
{
    /// The pipeline of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        let f = &cfg.front;
        Ok($name {
            clock: Default::default(),
            start: Default::default(),
            stop: Default::default(),
            reset: Default::default(),
            regs: Default::default(),
            load: Default::default(),
            load_address: Default::default(),
            load_data: Default::default(),
            in_valid: Default::default(),
            in_sop: Default::default(),
            in_live: Default::default(),
            out_valid: Default::default(),
            out_data: Default::default(),
            out_pop: Default::default(),
            out_count: Default::default(),
            running: Default::default(),
            accepting: Default::default(),
            ready: Default::default(),
            ended: Default::default(),
            config_error: Default::default(),
            framing_error: Default::default(),
            overflowed: Default::default(),
            fault: Default::default(),
            mask_loadable: Default::default(),
            mem_ready: Default::default(),
            mcb: Default::default(),
            control: StreamControl::new(cfg)?,
            mask: HotPixelMask::new(f)?,
            delay: <$($delay)*>::new(f)?,
            front: FrontHalf::new(f)?,
            back: BackHalf::new(cfg)?,
        })
    }
}

impl<
        const P: usize,
        const $dw: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
        const RAW: usize,
        const RCW: usize,
        const CAW2: usize,
        const BW: usize,
        const QAW: usize,
        const QW: usize,
        const PW: usize,
        const TW: usize,
        const TAW: usize,
        const OAW: usize,
    > Logic
    for $name<P, $dw, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>
{
    #[hdl_gen]
    fn update(&mut self) {
        clock!(self, clock, control, mask, delay, front, back);
        // Control.
        self.control.start.next = self.start.val() $(& self.mcb.$gate.val())*;
        self.control.stop.next = self.stop.val();
        self.control.reset.next = self.reset.val();
        RuntimeRegisters::link(&mut self.regs, &mut self.control.regs);
        self.control.back_done.next = self.back.done.val();
        self.control.in_valid.next = self.in_valid.val();
        self.control.in_sop.next = self.in_sop.val();
        self.control.in_live.next = self.in_live.val();
        // Stage 0: hot-pixel mask.
        // The mask is latched with the registers: loads only while stopped.
        self.mask_loadable.next = self.control.idle.val();
        self.mask.load.next = self.load.val() & self.mask_loadable.val();
        self.mask.load_address.next = self.load_address.val();
        self.mask.load_data.next = self.load_data.val();
        // (Siblings field by field: a join is a process per field in the
        // Verilog, [`crate::bundles`].)
        self.mask.word.valid.next = self.control.word.valid.val();
        self.mask.word.sop.next = self.control.word.sop.val();
        self.mask.word.flush.next = self.control.word.flush.val();
        self.mask.word.drain.next = self.control.word.drain.val();
        self.mask.word.live.next = self.control.word.live.val();
        self.mask.enable.next = self.control.mask_enable.val();
        // Stage 1a: delay line.
        self.delay.restart.next = self.control.restart.val();
        self.delay.n_window.next = self.control.settings.n_window.val();
        self.delay.word.valid.next = self.mask.out.valid.val();
        self.delay.word.sop.next = self.mask.out.sop.val();
        self.delay.word.flush.next = self.mask.out.flush.val();
        self.delay.word.drain.next = self.mask.out.drain.val();
        self.delay.word.live.next = self.mask.out.live.val();
        self.delay.side.next = self.mask.out_mask.val();
        $(McbPort::link(&mut self.mcb, &mut self.delay.$mcb_link);)?
        $(self.mem_ready.next = self.mcb.$ready_from.val();)?
        // Stages 1-4.
        self.front.restart.next = self.control.restart.val();
        self.front.threshold.next = self.control.threshold_hw.val();
        self.front.threshold_hold.next = self.control.threshold_hold_hw.val();
        self.front.word.valid.next = self.delay.out.valid.val();
        self.front.word.flush.next = self.delay.out.flush.val();
        self.front.word.drain.next = self.delay.out.drain.val();
        self.front.word.x.next = self.delay.out.x.val();
        self.front.word.y.next = self.delay.out.y.val();
        self.front.word.idx.next = self.delay.out.idx.val();
        self.front.word.live.next = self.delay.out.live.val();
        self.front.word.delayed.next = self.delay.out.delayed.val();
        self.front.word.side.next = self.delay.out.side.val();
        // Stages 5-7.
        self.back.restart.next = self.control.restart.val();
        self.back.emit_start.next = self.control.starting.val();
        self.back.settings.n_window.next = self.control.settings.n_window.val();
        self.back.settings.threshold.next = self.control.settings.threshold.val();
        self.back.settings.threshold_hold.next = self.control.settings.threshold_hold.val();
        self.back.settings.end_trim.next = self.control.settings.end_trim.val();
        self.back.settings.l_min.next = self.control.settings.l_min.val();
        self.back.settings.l_max.next = self.control.settings.l_max.val();
        self.back.settings.plane_period.next = self.control.settings.plane_period.val();
        self.back.settings.masked_pixels.next = self.control.settings.masked_pixels.val();
        self.back.stopping.next = self.control.stopping.val();
        self.back.planes_total.next = self.control.planes_total.val();
        self.back.fh.valid.next = self.front.out.valid.val();
        self.back.fh.flush.next = self.front.out.flush.val();
        self.back.fh.x.next = self.front.out.x.val();
        self.back.fh.y.next = self.front.out.y.val();
        self.back.fh.above.next = self.front.out.above.val();
        self.back.fh.candidate.next = self.front.out.candidate.val();
        self.back.raw.valid.next = self.delay.out.valid.val();
        self.back.raw.flush.next = self.delay.out.flush.val();
        self.back.raw.drain.next = self.delay.out.drain.val();
        self.back.raw.x.next = self.delay.out.x.val();
        self.back.raw.y.next = self.delay.out.y.val();
        self.back.raw.idx.next = self.delay.out.idx.val();
        self.back.raw.live.next = self.delay.out.live.val();
        self.back.raw.delayed.next = self.delay.out.delayed.val();
        self.back.raw.side.next = self.delay.out.side.val();
        self.back.out_pop.next = self.out_pop.val();
        self.out_valid.next = self.back.out_valid.val();
        self.out_data.next = self.back.out_data.val();
        self.out_count.next = self.back.out_count.val();
        self.running.next = self.control.running.val();
        self.accepting.next = self.control.accepting.val();
        self.ready.next = self.control.accepting.val() & self.back.room.val();
        self.ended.next = self.control.ended.val();
        self.config_error.next = self.control.config_error.val();
        self.framing_error.next = self.control.framing_error.val();
        self.overflowed.next = self.back.overflowed.val();
        self.fault.next = self.back.fault.val() $(| self.delay.$fault.val())*;
        $(self.$idle.next = $($idle_value)*;)*
        $(self.mcb.$mcb_idle.next = $($mcb_idle_value)*;)*
    }
}
    };
}

pipeline_block!(
    /// The whole pipeline with the block-RAM delay line: from the raw bit-plane
    /// words to the packet bytes. Type parameters: the front half's
    /// (`P, DAW, CW, CAW, VW, HW, LAW`, see [`crate::front_half`]) and the back
    /// half's (`RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW`, see
    /// [`BackHalf`] and [`BackHalfConfig`]).
    Pipeline, DAW,
    delay: { DelayLine<P, DAW, CW> },
    fault_doc: "An internal buffer overflowed.",
    mem_ready_doc: "Always high: no DDR2 to wait for.",
    mcb_doc: "The MCB port of [`PipelineDdr`], idle here (inputs unread, outputs 0), \
        so that one XEM6310 core ([`crate::xem6310_core`]) serves both delay lines.",
    gate: [],
    mcb_link: [],
    ready_from: [],
    faults: [],
    idle: [mem_ready = { true }],
    mcb_idle: [
        cmd_en = { false },
        cmd_instr = { 0.into() },
        cmd_bl = { 0.into() },
        cmd_addr = { 0.into() },
        wr_en = { false },
        wr_mask = { 0.into() },
        wr_data = { 0.into() },
        rd_en = { false }
    ]
);

pipeline_block!(
    /// The whole pipeline with the DDR2 delay line ([`DelayLineDdr`]) for
    /// configurations whose N_max planes do not fit block RAM: as [`Pipeline`],
    /// plus the MCB user port, and START waits for the memory's calibration
    /// (`mem_ready`). `PAW`: prefetch FIFO address bits.
    PipelineDdr, PAW,
    delay: { DelayLineDdr<P, CW, PAW> },
    fault_doc: "An internal buffer overflowed, or the DDR2 delay line under-ran.",
    mem_ready_doc: "The DDR2 memory has calibrated (START waits for it).",
    mcb_doc: "The MCB user port of the delay line's DDR2.",
    gate: [calib_done],
    mcb_link: [mcb],
    ready_from: [calib_done],
    faults: [underrun, write_error],
    idle: [],
    mcb_idle: []
);

/// The small simulation configuration: the front half's
/// [`crate::front_half::test_config`] (16×6, P = 4, k1 = [1 4 6 4 1],
/// N_max = 7) with M slots, R×R ROIs, r_assoc, L_max ≤ 64, a record queue
/// of 16 (its planes are so short that a Blink's packet takes several
/// planes), a 32-word tracker FIFO and a 2-KiB output FIFO.
pub fn test_back_config(
    slots: usize,
    roi_size: usize,
    r_assoc: u32,
) -> Result<BackHalfConfig, GatewareError> {
    let front = crate::front_half::test_config();
    let mut cfg = smartagg_model::config::PipelineConfig::new(
        front.width,
        front.height,
        front.n_max,
        front.kernel.clone(),
        front.kernel_shift,
        1,
    );
    cfg.slots = slots;
    cfg.roi_size = roi_size;
    cfg.r_assoc = r_assoc;
    cfg.l_max = 64;
    let mut b = BackHalfConfig::new(&cfg, front, 64)?;
    b.queue_log2 = 4;
    b.tracker_fifo_log2 = 5;
    b.output_fifo_log2 = 11;
    // Six rows beyond the default, so that `room` lets a paced source run
    // ahead of the sweep by more than its fixed lag even in this 6-row
    // field (with the default, `ring_room_rows` is the lag itself).
    b.row_slack = b.default_row_slack() + 6;
    b.validate()?;
    Ok(b)
}

/// The SPCImager at 150× (320×240, P = 16, N_max = 128, the model's kernel
/// for σ = 1.51 px) with the model's defaults M = 32, 9×9 ROIs (R = k),
/// r_assoc = 1 and L_max up to 65,535 planes (6.5 s).
pub fn spcimager150_back_config() -> Result<BackHalfConfig, GatewareError> {
    let front = crate::front_half::spcimager150_config();
    back_config_for(front, 108)
}

/// The projected SPCImager (78 % fill, 25 Hz DCR) at 150×: N ≈ 18, so the
/// delay line of N_max = 24 planes (1.84 Mbit) fits the block RAM of an
/// LX150; otherwise as [`spcimager150_back_config`].
pub fn projected150_back_config() -> Result<BackHalfConfig, GatewareError> {
    let front = GatewareConfig {
        n_max: 24,
        dsp_multipliers: crate::device::device_for(
            smartagg_model::params::PresetName::SpcimagerProjected,
        )
        .dsp48a1 as usize,
        ..crate::front_half::spcimager150_config()
    };
    back_config_for(front, 18)
}

fn back_config_for(front: GatewareConfig, n: u32) -> Result<BackHalfConfig, GatewareError> {
    let mut cfg = smartagg_model::config::PipelineConfig::new(
        front.width,
        front.height,
        n,
        front.kernel.clone(),
        front.kernel_shift,
        1,
    );
    cfg.slots = 32;
    cfg.roi_size = front.kernel.len();
    cfg.r_assoc = 1;
    BackHalfConfig::new(&cfg, front, 65_535)
}
