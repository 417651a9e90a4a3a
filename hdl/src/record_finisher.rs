//! The record finisher: the fields of a Blink record that follow from the
//! tracker's descriptor (t_s, t_e, planes summed, EDGE and PREROLL_CLIPPED)
//! and whether its counts are final, computed combinationally for the
//! packetiser ([`crate::packetiser::Packetiser`]). A sub-block of the
//! packetiser stage (stage 7; its model twin is `model/src/packetiser.rs`,
//! and the fields are those of the model's `Pipeline::emit` in
//! `model/src/pipeline.rs`).

use crate::config::{BackHalfConfig, GatewareConfig, GatewareError};
use rust_hdl::prelude::*;

/// The fields of a Blink record that follow from the tracker's descriptor,
/// as the model's `Pipeline::emit` computes them: `t_s = t_cross − ⌊N/2⌋`
/// (a continuation: `t_cross`), `t_e = t_drop − ⌊N/2⌋` (cut or truncated:
/// `t_drop`), planes summed `max(0, last + 1 − first)` with
/// `first = max(0, t_cross − N)` and `last = t_drop − N` (cut), `t_drop`
/// (truncated) or `t_drop − end_trim` (dropped) (PACKETS.md §8.6), EDGE
/// from the anchor, PREROLL_CLIPPED when `t_cross < N` (not a
/// continuation); the counts are final once the aggregator has swept the
/// record's plane. (A segment that summed no plane reads zero counts and
/// its ROI's mask flags from its bank like any other: the aggregator
/// swept it in its first plane.)
#[derive(LogicBlock)]
pub struct RecordFinisher<const NW: usize> {
    /// N register.
    pub n_window: Signal<In, Bits<NW>>,
    /// END_TRIM register.
    pub end_trim: Signal<In, Bits<NW>>,
    /// Planes the aggregator has swept.
    pub planes_done: Signal<In, Bits<48>>,
    /// Kind.
    pub kind: Signal<In, Bits<2>>,
    /// Tracker flags (CUT, CONTINUATION, TRUNCATED).
    pub flags: Signal<In, Bits<8>>,
    /// Anchor column.
    pub ax: Signal<In, Bits<16>>,
    /// Anchor row.
    pub ay: Signal<In, Bits<16>>,
    /// t_cross.
    pub t0: Signal<In, Bits<48>>,
    /// t_drop.
    pub t1: Signal<In, Bits<48>>,
    /// Tag.
    pub tag: Signal<In, Bits<48>>,
    /// Flags with EDGE and PREROLL_CLIPPED.
    pub o_flags: Signal<Out, Bits<8>>,
    /// t_s.
    pub o_ts: Signal<Out, Bits<48>>,
    /// t_e.
    pub o_te: Signal<Out, Bits<48>>,
    /// Planes summed.
    pub o_planes: Signal<Out, Bits<32>>,
    /// Counts final.
    pub o_ready: Signal<Out, Bit>,
    n48: Signal<Local, Bits<48>>,
    n32: Signal<Local, Bits<32>>,
    c32: Signal<Local, Bits<32>>,
    half: Signal<Local, Bits<48>>,
    cont: Signal<Local, Bit>,
    cut: Signal<Local, Bit>,
    trunc: Signal<Local, Bit>,
    /// `t_cross ≥ N`.
    t0_ge_n: Signal<Local, Bit>,
    /// The low 32 bits of t_drop − t_cross, and of t_drop + 1 (all the
    /// planes count needs: with `t_cross < N`, `t_drop < 2^32`).
    dt32: Signal<Local, Bits<32>>,
    t1p: Signal<Local, Bits<32>>,
    /// `N + 1 − end_trim`.
    nc1: Signal<Local, Bits<32>>,
    at_edge: Signal<Local, Bit>,
    f_edge: Signal<Local, Bits<8>>,
    f_clip: Signal<Local, Bits<8>>,
    h: Constant<Bits<16>>,
    last_x: Constant<Bits<16>>,
    last_y: Constant<Bits<16>>,
}

impl<const NW: usize> RecordFinisher<NW> {
    /// The finisher of a configuration.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        cfg.validate()?;
        GatewareConfig::check_width("RecordFinisher", "NW", NW, cfg.front.count_bits())?;
        let h = cfg.roi_half() as u64;
        Ok(RecordFinisher {
            n_window: Default::default(),
            end_trim: Default::default(),
            planes_done: Default::default(),
            kind: Default::default(),
            flags: Default::default(),
            ax: Default::default(),
            ay: Default::default(),
            t0: Default::default(),
            t1: Default::default(),
            tag: Default::default(),
            o_flags: Default::default(),
            o_ts: Default::default(),
            o_te: Default::default(),
            o_planes: Default::default(),
            o_ready: Default::default(),
            n48: Default::default(),
            n32: Default::default(),
            c32: Default::default(),
            half: Default::default(),
            cont: Default::default(),
            cut: Default::default(),
            trunc: Default::default(),
            t0_ge_n: Default::default(),
            dt32: Default::default(),
            t1p: Default::default(),
            nc1: Default::default(),
            at_edge: Default::default(),
            f_edge: Default::default(),
            f_clip: Default::default(),
            h: Constant::new(h.to_bits()),
            // ax + h ≥ W  ⟺  ax > W − 1 − h (W > 2h: R < H ≤ … and R ≤ P < W).
            last_x: Constant::new((cfg.front.width as u64 - 1 - h).to_bits()),
            last_y: Constant::new((cfg.front.height as u64 - 1 - h).to_bits()),
        })
    }
}

impl<const NW: usize> Logic for RecordFinisher<NW> {
    #[hdl_gen]
    fn update(&mut self) {
        self.n48.next = bit_cast::<48, NW>(self.n_window.val());
        self.n32.next = bit_cast::<32, NW>(self.n_window.val());
        self.c32.next = bit_cast::<32, NW>(self.end_trim.val());
        self.half.next = self.n48.val() >> 1;
        self.cut.next = self.flags.val().get_bit(2);
        self.cont.next = self.flags.val().get_bit(3);
        self.trunc.next = self.flags.val().get_bit(4);
        self.o_ts.next = self.t0.val() - self.half.val();
        if self.cont.val() {
            self.o_ts.next = self.t0.val();
        }
        self.o_te.next = self.t1.val() - self.half.val();
        if self.cut.val() | self.trunc.val() {
            self.o_te.next = self.t1.val();
        }
        // last + 1 − first in 32 bits, one form per case of first
        // (t_cross − N, or 0) and of last (t_drop − N, t_drop, t_drop −
        // end_trim), each computed beside the compares that pick one, so
        // that the compares and the subtractions are not in series.
        // With t_cross ≥ N: t_drop − t_cross + 1, + N, + N − end_trim.
        // With t_cross < N (a first segment): t_drop + 1 − N (0 unless
        // t_drop ≥ N), t_drop + 1, t_drop + 1 − end_trim (0 unless
        // t_drop ≥ end_trim).
        self.t0_ge_n.next = self.t0.val() >= self.n48.val();
        self.dt32.next = bit_cast::<32, 48>(self.t1.val()) - bit_cast::<32, 48>(self.t0.val());
        self.t1p.next = bit_cast::<32, 48>(self.t1.val()) + 1;
        self.nc1.next = self.n32.val() + 1 - self.c32.val();
        if self.t0_ge_n.val() {
            if self.cut.val() {
                self.o_planes.next = self.dt32.val() + 1;
            } else if self.trunc.val() {
                self.o_planes.next = self.dt32.val() + self.n32.val() + 1;
            } else {
                self.o_planes.next = self.dt32.val() + self.nc1.val();
            }
        } else if self.cut.val() {
            self.o_planes.next = 0.into();
            if self.t1.val() >= self.n48.val() {
                self.o_planes.next = self.t1p.val() - self.n32.val();
            }
        } else if self.trunc.val() {
            self.o_planes.next = self.t1p.val();
        } else {
            self.o_planes.next = 0.into();
            if bit_cast::<32, 48>(self.t1.val()) >= self.c32.val() {
                self.o_planes.next = self.t1p.val() - self.c32.val();
            }
        }
        self.at_edge.next = (self.ax.val() < self.h.val())
            | (self.ay.val() < self.h.val())
            | (self.ax.val() > self.last_x.val())
            | (self.ay.val() > self.last_y.val());
        self.f_edge.next = 0.into();
        if self.at_edge.val() {
            self.f_edge.next = 1.into();
        }
        self.f_clip.next = 0.into();
        if !self.cont.val() & !self.t0_ge_n.val() {
            self.f_clip.next = 0x20.into();
        }
        self.o_flags.next = self.flags.val() | self.f_edge.val() | self.f_clip.val();
        self.o_ready.next = (self.kind.val() != 1) | (self.planes_done.val() > self.tag.val());
    }
}
