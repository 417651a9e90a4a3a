//! Stage 0 — hot-pixel mask: masked pixels read as 0 everywhere downstream,
//! as [`smartagg_model::hot_pixel_mask::HotPixelMask::apply`].
//!
//! The mask is a memory of W·H bits (P per word) written through a load port
//! before the stream starts (the register "mask" of docs/DESIGN.md §3, taken at
//! stream start). The block sits in front of the delay line, so the delay
//! line, the counts and (later) the ROI sums all see the masked plane. It
//! numbers the words itself from `sop` and adds one clock of latency.

use crate::bram::{Bram, RamStyle};
use crate::bundles::{PlaneWord, PlaneWordOut};
use crate::config::{GatewareConfig, GatewareError};
use crate::stream::RasterPosition;
use rust_hdl::prelude::*;

/// `B AND NOT mask`, P pixels per clock. `AW`: mask address bits (the
/// counter memory's, one word per P pixels).
#[derive(LogicBlock)]
pub struct HotPixelMask<const P: usize, const AW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Mask load: write `load_data` (bit i = pixel i is hot) at word `load_address`.
    pub load: Signal<In, Bit>,
    /// Word index (raster order) of the mask word loaded.
    pub load_address: Signal<In, Bits<AW>>,
    /// The mask word.
    pub load_data: Signal<In, Bits<P>>,
    /// The word in (raw pixels; a drain plane's word is passed on).
    pub word: PlaneWord<P>,
    /// Apply the mask (the MASK_ENABLE register; off: nothing is masked).
    pub enable: Signal<In, Bit>,
    /// The word out, one clock later, its masked pixels 0.
    pub out: PlaneWordOut<P>,
    /// The mask bits of the word (for the ROI's MASKED flag).
    pub out_mask: Signal<Out, Bits<P>>,
    pos: RasterPosition,
    mask: Bram<P, AW>,
    v1: DFF<Bit>,
    s1: DFF<Bit>,
    f1: DFF<Bit>,
    d1: DFF<Bit>,
    en1: DFF<Bit>,
    live1: DFF<Bits<P>>,
}

impl<const P: usize, const AW: usize> HotPixelMask<P, AW> {
    /// The mask stage of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &GatewareConfig) -> Result<Self, GatewareError> {
        cfg.validate()?;
        GatewareConfig::check_width("HotPixelMask", "P", P, cfg.pixels_per_clock)?;
        GatewareConfig::check_width("HotPixelMask", "AW", AW, cfg.count_addr_bits())?;
        Ok(HotPixelMask {
            clock: Default::default(),
            load: Default::default(),
            load_address: Default::default(),
            load_data: Default::default(),
            word: Default::default(),
            enable: Default::default(),
            out: Default::default(),
            out_mask: Default::default(),
            pos: RasterPosition::new(cfg.words_per_row(), cfg.height),
            mask: Bram::new(cfg.words_per_plane(), RamStyle::Block),
            v1: Default::default(),
            s1: Default::default(),
            f1: Default::default(),
            d1: Default::default(),
            en1: Default::default(),
            live1: Default::default(),
        })
    }
}

impl<const P: usize, const AW: usize> Logic for HotPixelMask<P, AW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, v1, s1, f1, d1, en1, live1);
        self.pos.clock.next = self.clock.val();
        self.pos.valid.next = self.word.valid.val();
        self.pos.sop.next = self.word.sop.val();
        self.mask.clock.next = self.clock.val();
        self.mask.read_address.next = bit_cast::<AW, 32>(self.pos.idx.val());
        self.mask.write_address.next = self.load_address.val();
        self.mask.write_data.next = self.load_data.val();
        self.mask.write_enable.next = self.load.val();
        self.v1.d.next = self.word.valid.val();
        if self.word.valid.val() {
            self.s1.d.next = self.word.sop.val();
            self.f1.d.next = self.word.flush.val();
            self.d1.d.next = self.word.drain.val();
            self.en1.d.next = self.enable.val();
            self.live1.d.next = self.word.live.val();
        }
        self.out.valid.next = self.v1.q.val();
        self.out.sop.next = self.s1.q.val();
        self.out.flush.next = self.f1.q.val();
        self.out.drain.next = self.d1.q.val();
        self.out_mask.next = 0.into();
        if self.en1.q.val() {
            self.out_mask.next = self.mask.read_data.val();
        }
        self.out.live.next = self.live1.q.val() & !self.out_mask.val();
    }
}
