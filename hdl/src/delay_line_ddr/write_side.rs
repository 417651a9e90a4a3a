//! The DDR2 delay line's write side: it packs `K = 32/P` live stream words
//! into one 32-bit word (stream word k in bits `k·P …`), pushes each into
//! the MCB's write data FIFO (`wr_en`, `wr_data`), and gives one write
//! command per burst of `B` words (a plane's last burst may be shorter) at
//! `slot·2^SL + 4·first word`.
//!
//! A burst's command waits in a one-command register (`pend`) and goes out
//! on the clock after its last data word at the earliest (UG388: the data
//! must be in the write FIFO first). The port takes a waiting write before
//! anything else, so `waiting` and the command's length and address are
//! all this side offers the port's multiplexer.
//!
//! `issued` counts the words of the plane being written whose commands have
//! gone out (what the read side may read back of it); `plane_done` marks
//! the clock the plane's last command goes out, when `issued` returns to 0.
//!
//! **Restart.** A write still waiting goes out (its data is in the write
//! FIFO) but counts for nothing (`pend_old`). A burst cut short has its
//! words in the write FIFO without a command: one goes out for them, in the
//! old stream's slot, before the new stream's first (`spend`).
//!
//! **`error`** (sticky until a restart): a word was pushed into a full
//! write data FIFO, or a command had to be dropped (a new one was due while
//! one still waited).

use rust_hdl::prelude::*;

/// The write side of the DDR2 delay line. `P`: pixels per stream word;
/// `NW`: bits of the plane slot.
#[derive(LogicBlock)]
pub struct WriteSide<const P: usize, const NW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start.
    pub restart: Signal<In, Bit>,
    /// A stream word to store (a word of a plane that is neither the flush
    /// plane nor a drain plane).
    pub take: Signal<In, Bit>,
    /// The stream word's place in its 32-bit word, `k`.
    pub sub: Signal<In, Bits<16>>,
    /// The stream word is its 32-bit word's last (`k = K − 1`).
    pub last_sub: Signal<In, Bit>,
    /// Live pixels `B_t`.
    pub live: Signal<In, Bits<P>>,
    /// The plane's slot.
    pub slot: Signal<In, Bits<NW>>,
    /// The MCB's write data FIFO is full.
    pub wr_full: Signal<In, Bit>,
    /// The MCB's command FIFO is full.
    pub cmd_full: Signal<In, Bit>,
    /// Push `wr_data` into the write data FIFO.
    pub wr_en: Signal<Out, Bit>,
    /// The packed 32-bit word.
    pub wr_data: Signal<Out, Bits<32>>,
    /// A write command waits for the port.
    pub waiting: Signal<Out, Bit>,
    /// The waiting command's burst length − 1.
    pub cmd_bl: Signal<Out, Bits<6>>,
    /// The waiting command's byte address.
    pub cmd_addr: Signal<Out, Bits<30>>,
    /// Words of the plane being written whose commands have gone out.
    pub issued: Signal<Out, Bits<16>>,
    /// The plane's last write command goes out on this clock.
    pub plane_done: Signal<Out, Bit>,
    /// A word met a full write FIFO, or a command was dropped (sticky).
    pub error: Signal<Out, Bit>,
    acc: DFF<Bits<32>>,
    wcount: DFF<Bits<8>>,
    wstart: DFF<Bits<16>>,
    wword: DFF<Bits<16>>,
    wissued: DFF<Bits<16>>,
    pend: DFF<Bit>,
    pend_addr: DFF<Bits<30>>,
    pend_bl: DFF<Bits<6>>,
    /// The waiting write belongs to the stream before a restart.
    pend_old: DFF<Bit>,
    /// The waiting write is its plane's last burst.
    pend_last: DFF<Bit>,
    /// The command of a burst cut short by a restart.
    spend: DFF<Bit>,
    spend_addr: DFF<Bits<30>>,
    spend_bl: DFF<Bits<6>>,
    werr: DFF<Bit>,
    live32: Signal<Local, Bits<32>>,
    acc_next: Signal<Local, Bits<32>>,
    wdue: Signal<Local, Bit>,
    waddr: Signal<Local, Bits<30>>,
    wcmd_go: Signal<Local, Bit>,
    scmd_go: Signal<Local, Bit>,
    log2p: Constant<Bits<8>>,
    last_word: Constant<Bits<16>>,
    burst: Constant<Bits<16>>,
    slot_shift: Constant<Bits<8>>,
}

impl<const P: usize, const NW: usize> WriteSide<P, NW> {
    /// The write side for planes of `plane_words` 32-bit words in bursts of
    /// `burst` words, a slot every `2^slot_bits` bytes.
    pub fn new(plane_words: usize, burst: usize, slot_bits: usize) -> Self {
        assert!(P.is_power_of_two() && P <= 32, "P = {P}");
        assert!((1..=32).contains(&burst) && plane_words >= 1);
        let c16 = |v: u64| Constant::new(v.to_bits());
        let c8 = |v: u64| Constant::new(v.to_bits());
        WriteSide {
            clock: Default::default(),
            restart: Default::default(),
            take: Default::default(),
            sub: Default::default(),
            last_sub: Default::default(),
            live: Default::default(),
            slot: Default::default(),
            wr_full: Default::default(),
            cmd_full: Default::default(),
            wr_en: Default::default(),
            wr_data: Default::default(),
            waiting: Default::default(),
            cmd_bl: Default::default(),
            cmd_addr: Default::default(),
            issued: Default::default(),
            plane_done: Default::default(),
            error: Default::default(),
            acc: Default::default(),
            wcount: Default::default(),
            wstart: Default::default(),
            wword: Default::default(),
            wissued: Default::default(),
            pend: Default::default(),
            pend_addr: Default::default(),
            pend_bl: Default::default(),
            pend_old: Default::default(),
            pend_last: Default::default(),
            spend: Default::default(),
            spend_addr: Default::default(),
            spend_bl: Default::default(),
            werr: Default::default(),
            live32: Default::default(),
            acc_next: Default::default(),
            wdue: Default::default(),
            waddr: Default::default(),
            wcmd_go: Default::default(),
            scmd_go: Default::default(),
            log2p: c8(P.trailing_zeros() as u64),
            last_word: c16(plane_words as u64 - 1),
            burst: c16(burst as u64),
            slot_shift: c8(slot_bits as u64),
        }
    }
}

impl<const P: usize, const NW: usize> Logic for WriteSide<P, NW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(
            self, clock, acc, wcount, wstart, wword, wissued, pend, pend_addr, pend_bl, pend_old,
            pend_last, spend, spend_addr, spend_bl, werr
        );
        // ---- Pack K live words, one burst at a time.
        self.live32.next =
            bit_cast::<32, P>(self.live.val()) << (self.sub.val() << self.log2p.val());
        self.acc_next.next = self.acc.q.val() | self.live32.val();
        if self.sub.val() == 0 {
            self.acc_next.next = self.live32.val();
        }
        self.wr_en.next = false;
        self.wr_data.next = self.acc_next.val();
        self.wdue.next = false;
        if self.take.val() {
            self.acc.d.next = self.acc_next.val();
            if self.last_sub.val() {
                self.wr_en.next = true;
                if self.wr_full.val() {
                    self.werr.d.next = true;
                }
                self.wcount.d.next = self.wcount.q.val() + 1;
                self.wword.d.next = self.wword.q.val() + 1;
                if (bit_cast::<16, 8>(self.wcount.q.val()) + 1 == self.burst.val())
                    | (self.wword.q.val() == self.last_word.val())
                {
                    self.wdue.next = true;
                    self.wcount.d.next = 0.into();
                    self.wstart.d.next = self.wword.q.val() + 1;
                    if self.wword.q.val() == self.last_word.val() {
                        self.wword.d.next = 0.into();
                        self.wstart.d.next = 0.into();
                    }
                }
            }
        }
        self.waddr.next = (bit_cast::<30, NW>(self.slot.val()) << self.slot_shift.val())
            | (bit_cast::<30, 16>(self.wstart.q.val()) << 2);

        // ---- The waiting commands: a burst's first, then a cut burst's.
        self.wcmd_go.next = self.pend.q.val() & !self.cmd_full.val();
        self.plane_done.next = false;
        if self.wcmd_go.val() {
            self.pend.d.next = false;
            self.pend_old.d.next = false;
        }
        self.scmd_go.next = self.spend.q.val() & !self.pend.q.val() & !self.cmd_full.val();
        if self.scmd_go.val() {
            self.spend.d.next = false;
        }
        if self.wcmd_go.val() & !self.pend_old.q.val() {
            self.wissued.d.next =
                self.wissued.q.val() + bit_cast::<16, 6>(self.pend_bl.q.val()) + 1;
            if self.pend_last.q.val() {
                self.wissued.d.next = 0.into();
                self.plane_done.next = true;
            }
        }
        if self.wdue.val() {
            // (A write still waiting would go out after this one, or not at
            // all: flagged.)
            if (self.pend.q.val() & !self.wcmd_go.val())
                | (self.spend.q.val() & !self.scmd_go.val())
            {
                self.werr.d.next = true;
            }
            self.pend.d.next = true;
            self.pend_old.d.next = false;
            self.pend_addr.d.next = self.waddr.val();
            self.pend_bl.d.next = bit_cast::<6, 8>(self.wcount.q.val());
            self.pend_last.d.next = self.wword.q.val() == self.last_word.val();
        }
        self.waiting.next = self.pend.q.val() | self.spend.q.val();
        self.cmd_bl.next = self.spend_bl.q.val();
        self.cmd_addr.next = self.spend_addr.q.val();
        if self.pend.q.val() {
            self.cmd_bl.next = self.pend_bl.q.val();
            self.cmd_addr.next = self.pend_addr.q.val();
        }

        if self.restart.val() {
            self.wissued.d.next = 0.into();
            self.wcount.d.next = 0.into();
            self.wstart.d.next = 0.into();
            self.wword.d.next = 0.into();
            // A write waiting for the port, and the words of a burst cut
            // short, are the old stream's: they still go out, first.
            self.pend_old.d.next = self.pend.q.val() & !self.wcmd_go.val();
            self.werr.d.next = false;
            if self.wcount.q.val() != 0 {
                // Two cut bursts waiting at once (restarts faster than the
                // port takes commands) cannot both be kept: flagged.
                if self.spend.q.val() & !self.scmd_go.val() {
                    self.werr.d.next = true;
                }
                self.spend.d.next = true;
                self.spend_addr.d.next = self.waddr.val();
                self.spend_bl.d.next = bit_cast::<6, 8>(self.wcount.q.val() - 1);
            }
        }
        self.issued.next = self.wissued.q.val();
        self.error.next = self.werr.q.val();
    }
}
