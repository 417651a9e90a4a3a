//! Stream control: START's register check and latch (N, T_int, T_hold,
//! END_TRIM, L_min, L_max, the plane period, the masked-pixel count,
//! MASK_ENABLE), the restart of every block, the gating of the source at
//! plane boundaries, and at STOP the N drain planes and the flush plane
//! (see [`crate::pipeline`]). A block of the whole pipeline; its model
//! twin is `model/src/pipeline.rs` (`Pipeline::finish`), with the register
//! check of `model/src/config.rs` (`PipelineConfig::validate`).

use crate::bundles::{PlaneWordOut, RuntimeRegisters, StreamSettingsOut};
use crate::config::{BackHalfConfig, GatewareConfig, GatewareError};
use rust_hdl::prelude::*;

/// Stream-control states.
#[derive(Copy, Clone, Debug, PartialEq, LogicState)]
pub enum ControlState {
    /// No stream.
    Idle,
    /// START taken, the registers latched: their check (`regs_ok`, a
    /// register of the START clock's values) decides, a clock later.
    Check,
    /// Registers latched: restart every block.
    Restart,
    /// Passing the source's planes.
    Run,
    /// Sending the N drain planes.
    Drain,
    /// Sending the flush plane.
    Flush,
    /// Waiting for the last records.
    Ending,
}

/// Stream start and end: register check and latch, source gating at plane
/// boundaries, drain and flush planes. `NW`: bits of N; `HW`: bits of H.
#[derive(LogicBlock)]
pub struct StreamControl<const P: usize, const NW: usize, const HW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// START (one clock).
    pub start: Signal<In, Bit>,
    /// STOP (one clock).
    pub stop: Signal<In, Bit>,
    /// RESET (one clock, while stopped): clears the blocks and the status.
    pub reset: Signal<In, Bit>,
    /// The runtime registers as the host wrote them.
    pub regs: RuntimeRegisters,
    /// Back half done (StreamEnd out).
    pub back_done: Signal<In, Bit>,
    /// A source word.
    pub in_valid: Signal<In, Bit>,
    /// The source's first word of a plane.
    pub in_sop: Signal<In, Bit>,
    /// Its pixels.
    pub in_live: Signal<In, Bits<P>>,
    /// Restart every block (one clock).
    pub restart: Signal<Out, Bit>,
    /// The restart starts a stream (not a RESET).
    pub starting: Signal<Out, Bit>,
    /// No stream is being checked, started or run: the mask may be loaded.
    pub idle: Signal<Out, Bit>,
    /// The stream's settings, latched at START (StreamStart's fields;
    /// masked pixels are 0 without MASK_ENABLE).
    pub settings: StreamSettingsOut<NW>,
    /// Latched T_int, clamped to HW bits (front half).
    pub threshold_hw: Signal<Out, Bits<HW>>,
    /// Latched T_hold, clamped to HW bits (front half).
    pub threshold_hold_hw: Signal<Out, Bits<HW>>,
    /// Latched MASK_ENABLE.
    pub mask_enable: Signal<Out, Bit>,
    /// The word into the pipeline: a source word, or a word of a drain or
    /// the flush plane.
    pub word: PlaneWordOut<P>,
    /// No real plane after `planes_total`.
    pub stopping: Signal<Out, Bit>,
    /// Real planes of the stream.
    pub planes_total: Signal<Out, Bits<48>>,
    /// A stream is running.
    pub running: Signal<Out, Bit>,
    /// Source words are taken (the stream runs and STOP has not taken effect).
    pub accepting: Signal<Out, Bit>,
    /// The stream has ended (StreamEnd is in the output FIFO).
    pub ended: Signal<Out, Bit>,
    /// START was refused: a register is out of range (sticky until START/RESET).
    pub config_error: Signal<Out, Bit>,
    /// A source `sop` arrived inside a plane (sticky).
    pub framing_error: Signal<Out, Bit>,
    state: DFF<ControlState>,
    n: DFF<Bits<NW>>,
    thr: DFF<Bits<32>>,
    thr_hold: DFF<Bits<32>>,
    trim: DFF<Bits<NW>>,
    lmin: DFF<Bits<32>>,
    lmax: DFF<Bits<32>>,
    period: DFF<Bits<32>>,
    masked: DFF<Bits<32>>,
    men: DFF<Bit>,
    synced: DFF<Bit>,
    stop_req: DFF<Bit>,
    widx: DFF<Bits<32>>,
    /// `widx = 0` and `widx` = the plane's last word, as registers set
    /// beside `widx`: the source's gate (`accepting`, and so the replay
    /// FIFO's pop) and the word's plane end do not wait on 32-bit compares.
    w_zero: DFF<Bit>,
    w_last: DFF<Bit>,
    planes_in: DFF<Bits<48>>,
    drains: DFF<Bits<NW>>,
    /// N − 1, latched with N: the last drain plane is found by an equality
    /// with a register rather than behind an increment.
    n_last: DFF<Bits<NW>>,
    ended_q: DFF<Bit>,
    cfg_err: DFF<Bit>,
    frm_err: DFF<Bit>,
    /// `restart` as a register (it reaches every block): set on the clock
    /// that enters Restart, or that takes a RESET in Idle.
    rst: DFF<Bit>,
    /// The registers pass the model's validation: a register (the compares
    /// are 32-bit, and their result gates some fifty latching registers).
    regs_ok: DFF<Bit>,
    plane_end: Signal<Local, Bit>,
    /// A word enters the pipeline: `widx` steps (to 0 after the plane's
    /// last word).
    w_step: Signal<Local, Bit>,
    n_max: Constant<Bits<32>>,
    l_max_max: Constant<Bits<32>>,
    thr_max: Constant<Bits<32>>,
    last_widx: Constant<Bits<32>>,
    /// The word before the last (wraps for one-word planes, where it is
    /// never compared: every word is then the last).
    before_last_widx: Constant<Bits<32>>,
}

impl<const P: usize, const NW: usize, const HW: usize> StreamControl<P, NW, HW> {
    /// The control of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        let f = &cfg.front;
        GatewareConfig::check_width("StreamControl", "P", P, f.pixels_per_clock)?;
        GatewareConfig::check_width("StreamControl", "NW", NW, f.count_bits())?;
        GatewareConfig::check_width("StreamControl", "HW", HW, f.filtered_bits())?;
        if HW > 32 {
            return Err(GatewareError::Invalid {
                field: "n_max",
                value: f.n_max.to_string(),
                why: "H must fit 32 bits (the T_int register)".into(),
            });
        }
        let c32 = |v: u64| Constant::new(v.to_bits());
        Ok(StreamControl {
            clock: Default::default(),
            start: Default::default(),
            stop: Default::default(),
            reset: Default::default(),
            regs: Default::default(),
            back_done: Default::default(),
            in_valid: Default::default(),
            in_sop: Default::default(),
            in_live: Default::default(),
            restart: Default::default(),
            starting: Default::default(),
            idle: Default::default(),
            settings: Default::default(),
            threshold_hw: Default::default(),
            threshold_hold_hw: Default::default(),
            mask_enable: Default::default(),
            word: Default::default(),
            stopping: Default::default(),
            planes_total: Default::default(),
            running: Default::default(),
            accepting: Default::default(),
            ended: Default::default(),
            config_error: Default::default(),
            framing_error: Default::default(),
            state: Default::default(),
            n: Default::default(),
            thr: Default::default(),
            thr_hold: Default::default(),
            trim: Default::default(),
            lmin: Default::default(),
            lmax: Default::default(),
            period: Default::default(),
            masked: Default::default(),
            men: Default::default(),
            synced: Default::default(),
            stop_req: Default::default(),
            widx: Default::default(),
            w_zero: Default::default(),
            w_last: Default::default(),
            planes_in: Default::default(),
            drains: Default::default(),
            n_last: Default::default(),
            ended_q: Default::default(),
            cfg_err: Default::default(),
            frm_err: Default::default(),
            rst: Default::default(),
            regs_ok: Default::default(),
            plane_end: Default::default(),
            w_step: Default::default(),
            n_max: c32(f.n_max as u64),
            l_max_max: c32(cfg.l_max_max as u64),
            thr_max: c32((1u64 << HW) - 1),
            last_widx: c32(f.words_per_plane() as u64 - 1),
            before_last_widx: c32((f.words_per_plane() as u64).wrapping_sub(2) & 0xFFFF_FFFF),
        })
    }
}

// Match guards do not translate to Verilog, so the ifs stay inside the arms.
#[allow(clippy::collapsible_match)]
impl<const P: usize, const NW: usize, const HW: usize> Logic for StreamControl<P, NW, HW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(
            self, clock, state, n, thr, thr_hold, trim, lmin, lmax, period, masked, men, synced,
            stop_req, widx, w_zero, w_last, planes_in, drains, n_last, ended_q, cfg_err, frm_err,
            rst, regs_ok
        );
        // The model's PipelineConfig::validate, for the runtime registers.
        self.regs_ok.d.next = (self.regs.n.val() != 0)
            & (self.regs.n.val() <= self.n_max.val())
            & (self.regs.threshold.val() != 0)
            & (self.regs.threshold_hold.val() != 0)
            & (self.regs.threshold_hold.val() <= self.regs.threshold.val())
            & (self.regs.end_trim.val() < self.regs.n.val())
            & (self.regs.l_min.val() != 0)
            & (self.regs.l_max.val() >= self.regs.l_min.val())
            & (self.regs.l_max.val() >= self.regs.n.val())
            & (self.regs.l_max.val() <= self.l_max_max.val());
        self.plane_end.next = self.w_last.q.val();
        self.restart.next = self.rst.q.val();
        self.rst.d.next = false;
        self.starting.next = self.state.q.val() == ControlState::Restart;
        self.idle.next = self.state.q.val() == ControlState::Idle;
        self.word.valid.next = false;
        self.word.sop.next = self.w_zero.q.val();
        self.word.flush.next = false;
        self.word.drain.next = false;
        self.word.live.next = 0.into();
        self.w_step.next = false;

        match self.state.q.val() {
            ControlState::Idle => {
                if self.start.val() {
                    self.n.d.next = bit_cast::<NW, 32>(self.regs.n.val());
                    self.n_last.d.next = bit_cast::<NW, 32>(self.regs.n.val()) - 1;
                    self.thr.d.next = self.regs.threshold.val();
                    self.thr_hold.d.next = self.regs.threshold_hold.val();
                    self.trim.d.next = bit_cast::<NW, 32>(self.regs.end_trim.val());
                    self.lmin.d.next = self.regs.l_min.val();
                    self.lmax.d.next = self.regs.l_max.val();
                    self.period.d.next = self.regs.period.val();
                    self.masked.d.next = 0.into();
                    if self.regs.mask_enable.val() {
                        self.masked.d.next = self.regs.masked.val();
                    }
                    self.men.d.next = self.regs.mask_enable.val();
                    self.state.d.next = ControlState::Check;
                } else if self.reset.val() {
                    self.rst.d.next = true;
                    self.cfg_err.d.next = false;
                    self.frm_err.d.next = false;
                    self.ended_q.d.next = false;
                }
            }
            ControlState::Check => {
                if self.regs_ok.q.val() {
                    self.cfg_err.d.next = false;
                    self.frm_err.d.next = false;
                    self.ended_q.d.next = false;
                    self.state.d.next = ControlState::Restart;
                    self.rst.d.next = true;
                } else {
                    self.cfg_err.d.next = true;
                    self.state.d.next = ControlState::Idle;
                }
            }
            ControlState::Restart => {
                self.synced.d.next = false;
                self.stop_req.d.next = false;
                self.widx.d.next = 0.into();
                self.w_zero.d.next = true;
                self.w_last.d.next = self.last_widx.val() == 0;
                self.planes_in.d.next = 0.into();
                self.state.d.next = ControlState::Run;
            }
            ControlState::Run => {
                if self.stop.val() {
                    self.stop_req.d.next = true;
                }
                if self.stop_req.q.val() & self.w_zero.q.val() {
                    // At a plane boundary: no more real planes.
                    self.drains.d.next = 0.into();
                    if self.planes_in.q.val() == 0 {
                        self.state.d.next = ControlState::Ending;
                    } else {
                        self.state.d.next = ControlState::Drain;
                    }
                } else if self.in_valid.val() & (self.synced.q.val() | self.in_sop.val()) {
                    self.synced.d.next = true;
                    if self.in_sop.val() & !self.w_zero.q.val() {
                        self.frm_err.d.next = true;
                    }
                    self.word.valid.next = true;
                    self.word.live.next = self.in_live.val();
                    self.w_step.next = true;
                    if self.plane_end.val() {
                        self.planes_in.d.next = self.planes_in.q.val() + 1;
                    }
                }
            }
            ControlState::Drain => {
                self.word.valid.next = true;
                self.word.drain.next = true;
                self.w_step.next = true;
                if self.plane_end.val() {
                    self.drains.d.next = self.drains.q.val() + 1;
                    if self.drains.q.val() == self.n_last.q.val() {
                        self.state.d.next = ControlState::Flush;
                    }
                }
            }
            ControlState::Flush => {
                self.word.valid.next = true;
                self.word.flush.next = true;
                self.w_step.next = true;
                if self.plane_end.val() {
                    self.state.d.next = ControlState::Ending;
                }
            }
            ControlState::Ending => {
                if self.back_done.val() {
                    self.ended_q.d.next = true;
                    self.state.d.next = ControlState::Idle;
                }
            }
            _ => {}
        }
        if self.w_step.val() {
            if self.plane_end.val() {
                self.widx.d.next = 0.into();
                self.w_zero.d.next = true;
                self.w_last.d.next = self.last_widx.val() == 0;
            } else {
                self.widx.d.next = self.widx.q.val() + 1;
                self.w_zero.d.next = false;
                self.w_last.d.next = self.widx.q.val() == self.before_last_widx.val();
            }
        }

        self.settings.n_window.next = self.n.q.val();
        self.settings.threshold.next = self.thr.q.val();
        self.threshold_hw.next = bit_cast::<HW, 32>(self.thr.q.val());
        if self.thr.q.val() > self.thr_max.val() {
            self.threshold_hw.next = bit_cast::<HW, 32>(self.thr_max.val());
        }
        self.settings.threshold_hold.next = self.thr_hold.q.val();
        self.settings.end_trim.next = self.trim.q.val();
        self.threshold_hold_hw.next = bit_cast::<HW, 32>(self.thr_hold.q.val());
        if self.thr_hold.q.val() > self.thr_max.val() {
            self.threshold_hold_hw.next = bit_cast::<HW, 32>(self.thr_max.val());
        }
        self.settings.l_min.next = self.lmin.q.val();
        self.settings.l_max.next = self.lmax.q.val();
        self.settings.plane_period.next = self.period.q.val();
        self.settings.masked_pixels.next = self.masked.q.val();
        self.mask_enable.next = self.men.q.val();
        self.stopping.next = (self.state.q.val() == ControlState::Drain)
            | (self.state.q.val() == ControlState::Flush)
            | (self.state.q.val() == ControlState::Ending);
        self.planes_total.next = self.planes_in.q.val();
        self.running.next = (self.state.q.val() != ControlState::Idle)
            & (self.state.q.val() != ControlState::Check)
            & (self.state.q.val() != ControlState::Restart);
        // STOP waits for the plane in progress to complete.
        self.accepting.next = (self.state.q.val() == ControlState::Run)
            & !(self.stop_req.q.val() & self.w_zero.q.val());
        self.ended.next = self.ended_q.q.val();
        self.config_error.next = self.cfg_err.q.val();
        self.framing_error.next = self.frm_err.q.val();
    }
}
