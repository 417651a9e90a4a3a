//! The DDR2 delay line's read side: it walks the written planes in order,
//! slot after slot (`0 … N − 1`, then 0 again), one burst at a time, and
//! moves the words the MCB returns into the prefetch FIFO.
//!
//! **A read is decided** (`fill`) when the next burst is written (its
//! plane is complete, or its words' write commands have gone out: read
//! after write, in order on the port) and its words fit the FIFO beside
//! the reads in flight, and waits in a one-command register (`rpend`) for
//! the port, behind any waiting write (`write_waiting`). Both conditions are
//! registers computed on the clock before: a decision blocks the next
//! clock's (its command still waits), and between decisions the two can
//! only lag towards caution (more writes issued, more words popped), so the
//! decision path starts at registers. The burst after the one decided is
//! known in advance (every burst is full but a plane's last).
//!
//! **Restart.** Reads in flight, and a read still waiting (it goes out),
//! belong to the old stream: their words are counted into `discard` and
//! dropped as they arrive, over any number of restarts. No word moves on a
//! restart's clock, so the count handed over is exact, and only words this
//! side asked for move (a port that powers up showing a word does not
//! unbalance the count).

use rust_hdl::prelude::*;

/// The read side of the DDR2 delay line. `NW`: bits of the plane slot.
#[derive(LogicBlock)]
pub struct ReadSide<const NW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start.
    pub restart: Signal<In, Bit>,
    /// The MCB has calibrated.
    pub calib_done: Signal<In, Bit>,
    /// The last slot, N − 1.
    pub n_last: Signal<In, Bits<NW>>,
    /// Words of the plane being written whose write commands have gone out.
    pub issued: Signal<In, Bits<16>>,
    /// The plane being written has had its last write command go out.
    pub plane_done: Signal<In, Bit>,
    /// Words in the prefetch FIFO.
    pub fifo_count: Signal<In, Bits<16>>,
    /// A write command waits for the port (it goes first).
    pub write_waiting: Signal<In, Bit>,
    /// The MCB's command FIFO is full.
    pub cmd_full: Signal<In, Bit>,
    /// The MCB's read data FIFO is empty.
    pub rd_empty: Signal<In, Bit>,
    /// A read command waits for the port.
    pub waiting: Signal<Out, Bit>,
    /// The waiting read's burst length − 1.
    pub cmd_bl: Signal<Out, Bits<6>>,
    /// The waiting read's byte address.
    pub cmd_addr: Signal<Out, Bits<30>>,
    /// Take the head read word.
    pub rd_en: Signal<Out, Bit>,
    /// Push the taken word into the prefetch FIFO (it is not discarded).
    pub push: Signal<Out, Bit>,
    rslot: DFF<Bits<NW>>,
    rword: DFF<Bits<16>>,
    rfinal: DFF<Bit>,
    /// Planes the writer has completed beyond the one being read.
    ahead: DFF<Bits<16>>,
    outstanding: DFF<Bits<16>>,
    discard: DFF<Bits<16>>,
    readable: DFF<Bit>,
    room_ok: DFF<Bit>,
    rpend: DFF<Bit>,
    rpend_addr: DFF<Bits<30>>,
    rpend_bl: DFF<Bits<6>>,
    rlen: Signal<Local, Bits<16>>,
    written: Signal<Local, Bit>,
    fill: Signal<Local, Bit>,
    rcmd_addr: Signal<Local, Bits<30>>,
    rcmd_go: Signal<Local, Bit>,
    rnext: Signal<Local, Bits<16>>,
    rfin: Signal<Local, Bit>,
    transfer: Signal<Local, Bit>,
    pushed: Signal<Local, Bit>,
    out_add: Signal<Local, Bits<16>>,
    burst: Constant<Bits<16>>,
    last_start: Constant<Bits<16>>,
    last_len: Constant<Bits<16>>,
    one_burst: Constant<Bit>,
    slot_shift: Constant<Bits<8>>,
    cap: Constant<Bits<16>>,
}

impl<const NW: usize> ReadSide<NW> {
    /// The read side for planes of `plane_words` 32-bit words in bursts of
    /// `burst` words, a slot every `2^slot_bits` bytes, into a prefetch
    /// FIFO of `cap` words.
    pub fn new(plane_words: usize, burst: usize, slot_bits: usize, cap: usize) -> Self {
        assert!((1..=32).contains(&burst) && plane_words >= 1);
        let last_start = plane_words.div_ceil(burst) * burst - burst;
        let c16 = |v: u64| Constant::new(v.to_bits());
        ReadSide {
            clock: Default::default(),
            restart: Default::default(),
            calib_done: Default::default(),
            n_last: Default::default(),
            issued: Default::default(),
            plane_done: Default::default(),
            fifo_count: Default::default(),
            write_waiting: Default::default(),
            cmd_full: Default::default(),
            rd_empty: Default::default(),
            waiting: Default::default(),
            cmd_bl: Default::default(),
            cmd_addr: Default::default(),
            rd_en: Default::default(),
            push: Default::default(),
            rslot: Default::default(),
            rword: Default::default(),
            rfinal: Default::default(),
            ahead: Default::default(),
            outstanding: Default::default(),
            discard: Default::default(),
            readable: Default::default(),
            room_ok: Default::default(),
            rpend: Default::default(),
            rpend_addr: Default::default(),
            rpend_bl: Default::default(),
            rlen: Default::default(),
            written: Default::default(),
            fill: Default::default(),
            rcmd_addr: Default::default(),
            rcmd_go: Default::default(),
            rnext: Default::default(),
            rfin: Default::default(),
            transfer: Default::default(),
            pushed: Default::default(),
            out_add: Default::default(),
            burst: c16(burst as u64),
            last_start: c16(last_start as u64),
            last_len: c16((plane_words - last_start) as u64),
            one_burst: Constant::new(last_start == 0),
            slot_shift: Constant::new((slot_bits as u64).to_bits()),
            cap: c16(cap as u64),
        }
    }
}

impl<const NW: usize> Logic for ReadSide<NW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(
            self,
            clock,
            rslot,
            rword,
            rfinal,
            ahead,
            outstanding,
            discard,
            readable,
            room_ok,
            rpend,
            rpend_addr,
            rpend_bl
        );
        self.rlen.next = self.burst.val();
        if self.rfinal.q.val() {
            self.rlen.next = self.last_len.val();
        }
        // `ahead` is never negative; the sign is checked all the same.
        self.written.next = ((self.ahead.q.val() != 0) & !self.ahead.q.val().get_bit(15))
            | ((self.ahead.q.val() == 0)
                & (self.rword.q.val() + self.rlen.val() <= self.issued.val()));
        self.readable.d.next = self.written.val();
        self.room_ok.d.next =
            self.fifo_count.val() + self.outstanding.q.val() + self.rlen.val() <= self.cap.val();
        self.fill.next = self.calib_done.val()
            & !self.rpend.q.val()
            & self.readable.q.val()
            & self.room_ok.q.val()
            & !self.restart.val();
        self.rcmd_addr.next = (bit_cast::<30, NW>(self.rslot.q.val()) << self.slot_shift.val())
            | (bit_cast::<30, 16>(self.rword.q.val()) << 2);
        self.rcmd_go.next = self.rpend.q.val() & !self.write_waiting.val() & !self.cmd_full.val();
        if self.rcmd_go.val() {
            self.rpend.d.next = false;
        }
        self.rnext.next = self.rword.q.val() + self.burst.val();
        self.rfin.next = self.fill.val() & self.rfinal.q.val();
        if self.fill.val() {
            self.rpend.d.next = true;
            self.rpend_addr.d.next = self.rcmd_addr.val();
            self.rpend_bl.d.next = bit_cast::<6, 16>(self.rlen.val() - 1);
            self.rword.d.next = self.rnext.val();
            self.rfinal.d.next = self.rnext.val() == self.last_start.val();
            if self.rfinal.q.val() {
                self.rword.d.next = 0.into();
                self.rfinal.d.next = self.one_burst.val();
                if self.rslot.q.val() == self.n_last.val() {
                    self.rslot.d.next = 0.into();
                } else {
                    self.rslot.d.next = self.rslot.q.val() + 1;
                }
            }
        }
        if self.plane_done.val() & !self.rfin.val() {
            self.ahead.d.next = self.ahead.q.val() + 1;
        }
        if self.rfin.val() & !self.plane_done.val() {
            self.ahead.d.next = self.ahead.q.val() - 1;
        }
        self.transfer.next = !self.rd_empty.val()
            & !self.restart.val()
            & ((self.outstanding.q.val() != 0) | (self.discard.q.val() != 0));
        self.rd_en.next = self.transfer.val();
        self.pushed.next = self.transfer.val() & (self.discard.q.val() == 0);
        self.push.next = self.pushed.val();
        self.out_add.next = 0.into();
        if self.fill.val() {
            self.out_add.next = self.rlen.val();
        }
        self.outstanding.d.next = self.outstanding.q.val() + self.out_add.val();
        if self.pushed.val() {
            self.outstanding.d.next = self.outstanding.q.val() + self.out_add.val() - 1;
        }
        if self.transfer.val() & (self.discard.q.val() != 0) {
            self.discard.d.next = self.discard.q.val() - 1;
        }
        self.waiting.next = self.rpend.q.val();
        self.cmd_bl.next = self.rpend_bl.q.val();
        self.cmd_addr.next = self.rpend_addr.q.val();

        if self.restart.val() {
            self.rslot.d.next = 0.into();
            self.rword.d.next = 0.into();
            self.rfinal.d.next = self.one_burst.val();
            self.ahead.d.next = 0.into();
            self.readable.d.next = false;
            self.room_ok.d.next = false;
            self.outstanding.d.next = 0.into();
            self.discard.d.next = self.discard.q.val() + self.outstanding.q.val();
        }
    }
}
