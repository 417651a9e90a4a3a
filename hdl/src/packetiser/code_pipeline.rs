//! The code pipeline of a Blink's count block: the ROI's counts, one a
//! clock from the count streamer, become Rice codes in three registered
//! stages, so that no path is deeper than one barrel shifter or one
//! thermometer:
//! * A, the offset `d = count − base` (pass 2 reads it too: its code
//!   lengths for every k);
//! * B, the quotient `d >> k`;
//! * C, the code and its length ([`RiceCode`]), which the bit packer
//!   appends.
//!
//! A stage takes the one before it when it is empty or its content moves
//! on this clock (`ready` is stage A's: the streamer's count is taken). In
//! pass 2 the offsets stop in A (B takes nothing); in Codes they flow
//! through to C, whose code leaves when `code_taken`. A restart empties
//! every stage.

use super::RiceCode;
use rust_hdl::prelude::*;

/// Three registered stages from counts to Rice codes. `RCW`: count bits.
#[derive(LogicBlock)]
pub struct CodePipeline<const RCW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: every stage empty.
    pub restart: Signal<In, Bit>,
    /// Pass 2: counts enter stage A and go no further.
    pub pass2: Signal<In, Bit>,
    /// Codes: counts flow through A, B and C to the bit packer.
    pub codes: Signal<In, Bit>,
    /// The count streamer's count.
    pub count: Signal<In, Bits<RCW>>,
    /// The count is valid.
    pub count_valid: Signal<In, Bit>,
    /// The ROI's minimum count.
    pub base: Signal<In, Bits<RCW>>,
    /// The Rice parameter (< 32; steady from a clock before Codes on).
    pub k: Signal<In, Bits<8>>,
    /// Stage C's code, if it holds one, leaves this clock.
    pub code_taken: Signal<In, Bit>,
    /// Stage A takes the count this clock (or has room for it).
    pub ready: Signal<Out, Bit>,
    /// Stage A holds an offset.
    pub a_valid: Signal<Out, Bit>,
    /// Stage A's offset from the base.
    pub a_offset: Signal<Out, Bits<RCW>>,
    /// Stage B holds a quotient.
    pub b_valid: Signal<Out, Bit>,
    /// Stage C holds a code.
    pub c_valid: Signal<Out, Bit>,
    /// Stage C's code, right aligned.
    pub code: Signal<Out, Bits<64>>,
    /// Its length in bits.
    pub len: Signal<Out, Bits<8>>,
    a_v: DFF<Bit>,
    a_d: DFF<Bits<RCW>>,
    b_v: DFF<Bit>,
    b_q: DFF<Bits<32>>,
    b_d: DFF<Bits<RCW>>,
    c_v: DFF<Bit>,
    c_code: DFF<Bits<64>>,
    c_len: DFF<Bits<8>>,
    /// Stage C from B.
    coder: RiceCode<RCW>,
    free_a: Signal<Local, Bit>,
    free_b: Signal<Local, Bit>,
    free_c: Signal<Local, Bit>,
}

impl<const RCW: usize> Default for CodePipeline<RCW> {
    fn default() -> Self {
        CodePipeline {
            clock: Default::default(),
            restart: Default::default(),
            pass2: Default::default(),
            codes: Default::default(),
            count: Default::default(),
            count_valid: Default::default(),
            base: Default::default(),
            k: Default::default(),
            code_taken: Default::default(),
            ready: Default::default(),
            a_valid: Default::default(),
            a_offset: Default::default(),
            b_valid: Default::default(),
            c_valid: Default::default(),
            code: Default::default(),
            len: Default::default(),
            a_v: Default::default(),
            a_d: Default::default(),
            b_v: Default::default(),
            b_q: Default::default(),
            b_d: Default::default(),
            c_v: Default::default(),
            c_code: Default::default(),
            c_len: Default::default(),
            coder: Default::default(),
            free_a: Default::default(),
            free_b: Default::default(),
            free_c: Default::default(),
        }
    }
}

impl<const RCW: usize> Logic for CodePipeline<RCW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, a_v, a_d, b_v, b_q, b_d, c_v, c_code, c_len);
        self.free_c.next = !self.c_v.q.val() | self.code_taken.val();
        self.free_b.next = !self.b_v.q.val() | self.free_c.val();
        self.free_a.next = !self.a_v.q.val() | self.free_b.val();
        // C from B: the code and its length.
        self.coder.clock.next = self.clock.val();
        self.coder.k.next = self.k.val();
        self.coder.quotient.next = self.b_q.q.val();
        self.coder.offset.next = self.b_d.q.val();
        if self.free_c.val() {
            self.c_v.d.next = self.b_v.q.val();
            self.c_code.d.next = self.coder.code.val();
            self.c_len.d.next = self.coder.len.val();
        }
        // B from A: the quotient.
        if self.free_b.val() {
            self.b_v.d.next = self.a_v.q.val() & self.codes.val();
            self.b_q.d.next = bit_cast::<32, RCW>(self.a_d.q.val()) >> self.k.val();
            self.b_d.d.next = self.a_d.q.val();
        }
        // A from the streamer: the offset.
        if self.free_a.val() {
            self.a_v.d.next = (self.codes.val() | self.pass2.val()) & self.count_valid.val();
            self.a_d.d.next = self.count.val() - self.base.val();
        }
        if self.restart.val() {
            self.a_v.d.next = false;
            self.b_v.d.next = false;
            self.c_v.d.next = false;
        }
        self.ready.next = self.free_a.val();
        self.a_valid.next = self.a_v.q.val();
        self.a_offset.next = self.a_d.q.val();
        self.b_valid.next = self.b_v.q.val();
        self.c_valid.next = self.c_v.q.val();
        self.code.next = self.c_code.q.val();
        self.len.next = self.c_len.q.val();
    }
}
