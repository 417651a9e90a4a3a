//! The DDR2 delay line's write and read sides, each against its definition
//! with a port emulated around it (`hdl/src/delay_line_ddr/`):
//! * the write side: every word it pushes lands, by the write command that
//!   takes it from the write FIFO, at its own address (its plane's slot,
//!   its place in the plane), packed from its K stream words; no word is
//!   left without a command, over restarts that cut bursts short; `issued`
//!   and `plane_done` follow the current stream's commands; the error flag
//!   is raised by a full write FIFO and by a command it had to drop;
//! * the read side: it pushes the words of the planes in the walk's order
//!   (slot 0, 1, …, N − 1, 0, …), reads only words whose write commands
//!   have gone out, never asks for more than the prefetch FIFO holds, gives
//!   the port to a waiting write, and after a restart drops every word of
//!   the reads still in flight and walks from slot 0 again.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::delay_line_ddr::{ReadSide, WriteSide};
use smartagg_hdl::testbench::bench::{settle, Bench};
use std::collections::{HashMap, VecDeque};

const P: usize = 4;
const K: usize = 32 / P;
const NW: usize = 3;

/// Runs the write side over `planes` planes of `plane_words` 32-bit words
/// in bursts of `burst`, with random gaps, a command FIFO full
/// `cmd_full_pct` % of clocks and a restart every `restart_every` stream
/// words on average (0: never; else four). Returns the error flag at the
/// end and the commands that went out for an earlier stream's words.
fn run_write_side(
    seed: u64,
    plane_words: usize,
    burst: usize,
    planes: usize,
    cmd_full_pct: u32,
    restart_every: u32,
) -> (bool, usize) {
    let slot_bits = 12;
    let n = 3;
    let mut b = Bench::new(
        WriteSide::<P, NW>::new(plane_words, burst, slot_bits),
        |u| &mut u.clock,
    );
    let mut rng = common::rng(seed);
    // The write FIFO: each word with the address it belongs at and the
    // stream (generation) and plane it came from.
    let mut fifo: VecDeque<(u32, u64, usize, usize)> = VecDeque::new();
    let mut memory: HashMap<u64, u32> = HashMap::new();
    let mut last_stream: HashMap<u64, u32> = HashMap::new();
    let (mut gen, mut plane, mut word, mut sub) = (0usize, 0usize, 0usize, 0usize);
    let mut acc = 0u32;
    // Words of each plane of the current stream whose commands went out.
    let mut issued: HashMap<usize, usize> = HashMap::new();
    let (mut cmds, mut old_cmds, mut restarts, mut plane_dones) = (0, 0, 0, 0);
    let mut clocks = 0;
    let mut idle = 0;
    while idle < 200 {
        clocks += 1;
        assert!(clocks < 2_000_000, "write side did not finish");
        let u = &mut b.uut;
        // Four restarts at random (one at the latest when a stream ends),
        // then a last stream to its end.
        let finished = plane == planes;
        let restart = restart_every > 0
            && restarts < 4
            && (finished || rng.gen_range(0..restart_every) == 0)
            && plane + word + sub > 0;
        let done = finished && !restart;
        let take = !restart && !done && rng.gen_range(0..4) != 0;
        let live = rng.gen_range(0..1u64 << P);
        u.restart.next = restart;
        u.take.next = take;
        u.sub.next = (sub as u64).to_bits();
        u.last_sub.next = sub == K - 1;
        u.live.next = live.to_bits();
        u.slot.next = ((plane % n) as u64).to_bits();
        u.wr_full.next = false;
        u.cmd_full.next = rng.gen_range(0..100) < cmd_full_pct;
        settle(u);
        // The port takes a waiting write when the command FIFO has room.
        if u.waiting.val() && !u.cmd_full.val() {
            let len = u.cmd_bl.val().to_u64() as usize + 1;
            assert!(len <= burst, "a burst of {len} words");
            let addr = u.cmd_addr.val().to_u64();
            assert_eq!(addr % 4, 0);
            let mut covers = None;
            for i in 0..len {
                let (data, at, g, p) = fifo.pop_front().expect("a command without its words");
                assert_eq!(
                    addr / 4 + i as u64,
                    at,
                    "word {i} of a command at {addr:#x}"
                );
                memory.insert(at, data);
                covers = Some((g, p));
            }
            let (g, p) = covers.unwrap();
            let whole = if g == gen {
                let w = issued.entry(p).or_default();
                *w += len;
                *w == plane_words
            } else {
                false
            };
            assert_eq!(u.plane_done.val(), whole, "plane_done, plane {p}");
            plane_dones += whole as usize;
            cmds += 1;
            old_cmds += (g != gen) as usize;
        } else {
            assert!(!u.plane_done.val());
        }
        if take {
            acc = if sub == 0 { 0 } else { acc };
            acc |= (live as u32) << (sub * P);
            assert_eq!(u.wr_en.val(), sub == K - 1);
            if sub == K - 1 {
                assert_eq!(u.wr_data.val().to_u64() as u32, acc);
                let at = (((plane % n) << slot_bits) / 4 + word) as u64;
                fifo.push_back((acc, at, gen, plane));
                last_stream.insert(at, acc);
            }
        } else {
            assert!(!u.wr_en.val());
        }
        b.tick();
        if restart {
            gen += 1;
            restarts += 1;
            (plane, word, sub) = (0, 0, 0);
            issued.clear();
            last_stream.clear();
        } else if take {
            sub += 1;
            if sub == K {
                sub = 0;
                word += 1;
                if word == plane_words {
                    word = 0;
                    plane += 1;
                }
            }
        }
        // `issued`: the current stream's plane whose commands are going out.
        let current = (0..).find(|p| issued.get(p).copied().unwrap_or(0) < plane_words);
        let expect = issued.get(&current.unwrap()).copied().unwrap_or(0);
        assert_eq!(b.uut.issued.val().to_u64() as usize, expect, "issued");
        idle = if done && fifo.is_empty() { idle + 1 } else { 0 };
    }
    assert!(!b.uut.waiting.val());
    if restart_every == 0 {
        assert_eq!(plane_dones, planes);
    } else {
        assert!(plane_dones >= planes);
    }
    assert!(cmds >= planes * plane_words / burst);
    assert_eq!(restarts, if restart_every > 0 { 4 } else { 0 });
    // The last stream's planes are whole in memory.
    assert_eq!(last_stream.len(), planes.min(n) * plane_words);
    for (at, data) in &last_stream {
        assert_eq!(memory.get(at), Some(data), "word at {at:#x}");
    }
    (b.uut.error.val(), old_cmds)
}

#[test]
fn write_side_puts_every_word_at_its_address() {
    for (seed, plane_words, burst) in [(1, 37, 4), (2, 256, 32), (3, 5, 1)] {
        let (err, old) = run_write_side(seed, plane_words, burst, 7, 40, 0);
        assert!(!err, "error flag, {plane_words} words in bursts of {burst}");
        assert_eq!(old, 0);
    }
}

#[test]
fn write_side_restarts_leave_no_word_without_a_command() {
    for (seed, plane_words, burst) in [(4, 37, 4), (5, 64, 8)] {
        let (err, old) = run_write_side(seed, plane_words, burst, 6, 30, 900);
        assert!(!err, "error flag after restarts");
        // The cut bursts (and writes still waiting) went out after their
        // restart, for the old stream's words.
        assert!(old >= 2, "{old} commands of an earlier stream");
    }
}

#[test]
fn write_side_flags_a_full_fifo_and_a_dropped_command() {
    // A word pushed into a full write FIFO.
    let mut b = Bench::new(WriteSide::<P, NW>::new(16, 2, 8), |u| &mut u.clock);
    let u = &mut b.uut;
    u.restart.next = true;
    b.tick();
    let u = &mut b.uut;
    u.restart.next = false;
    u.take.next = true;
    u.last_sub.next = true;
    u.wr_full.next = true;
    b.tick();
    assert!(b.uut.error.val(), "full write FIFO");
    b.uut.take.next = false;
    b.uut.wr_full.next = false;
    b.tick();
    assert!(b.uut.error.val(), "the flag is sticky");
    b.uut.restart.next = true;
    b.tick();
    b.uut.restart.next = false;
    b.tick();
    assert!(!b.uut.error.val(), "a restart clears it");
    // The command FIFO full for longer than a burst takes: the next burst
    // is due while the last still waits.
    b.uut.cmd_full.next = true;
    b.uut.take.next = true;
    b.uut.last_sub.next = true;
    for _ in 0..4 {
        assert!(!b.uut.error.val());
        b.tick();
    }
    assert!(b.uut.error.val(), "a dropped command");
}

/// The read side over planes of `plane_words` words in bursts of `burst`,
/// N = `n`, a prefetch FIFO of `cap` words, a port with 6 clocks of
/// latency, with a restart at clock `restart_at` (if any).
fn run_read_side(
    seed: u64,
    plane_words: usize,
    burst: usize,
    n: usize,
    cap: usize,
    restart_at: Option<usize>,
) {
    let slot_bits = 12;
    let mut b = Bench::new(
        ReadSide::<NW>::new(plane_words, burst, slot_bits, cap),
        |u| &mut u.clock,
    );
    let mut rng = common::rng(seed);
    let latency = 6;
    let mut gen = 0u64;
    // Words in flight: (ready at clock, data = gen << 32 | word address).
    let mut port: VecDeque<(usize, u64)> = VecDeque::new();
    let mut prefetch: VecDeque<u64> = VecDeque::new();
    // The emulated write side: planes complete, words of the current one
    // whose commands have gone out (a register, as `issued`).
    let (mut w_planes, mut w_issued) = (0usize, 0usize);
    // The walk: words pushed, words asked for.
    let (mut pushed, mut asked) = (0usize, 0usize);
    // A read decided before the restart still waits for the port.
    let mut old_waiting = false;
    let (mut dropped, mut restarted) = (0usize, restart_at.is_none());
    let target = 5 * n * plane_words;
    let mut clock = 0usize;
    b.uut.restart.next = true;
    b.uut.n_last.next = ((n - 1) as u64).to_bits();
    b.tick();
    while pushed < target || !restarted {
        clock += 1;
        assert!(clock < 500_000, "read side stalled");
        let restart = restart_at == Some(clock);
        let u = &mut b.uut;
        // The writer issues 1 to B words at random (the read side must not
        // rely on the write side's bursts), at most N planes ahead of the
        // reader (it would overwrite unread slots).
        let issue = !restart && rng.gen_range(0..3) == 0 && w_planes < pushed / plane_words + n;
        let w_next = (w_issued + rng.gen_range(1..=burst)).min(plane_words);
        let plane_done = issue && w_next == plane_words;
        let write_waiting = rng.gen_range(0..5) == 0;
        u.restart.next = restart;
        u.calib_done.next = true;
        u.issued.next = (w_issued as u64).to_bits();
        u.plane_done.next = plane_done;
        u.fifo_count.next = (prefetch.len() as u64).to_bits();
        u.write_waiting.next = write_waiting;
        u.cmd_full.next = rng.gen_range(0..6) == 0;
        let head = port.front().filter(|(at, _)| *at <= clock).map(|w| w.1);
        u.rd_empty.next = head.is_none();
        settle(u);
        if u.waiting.val() && !write_waiting && !u.cmd_full.val() {
            let len = u.cmd_bl.val().to_u64() as usize + 1;
            let addr = u.cmd_addr.val().to_u64() as usize;
            let tag = if old_waiting { gen - 1 } else { gen };
            if !old_waiting {
                // The walk's next burst.
                let (t, j) = (asked / plane_words, asked % plane_words);
                assert_eq!(
                    addr,
                    ((t % n) << slot_bits) + 4 * j,
                    "read of plane {t} word {j}"
                );
                assert_eq!(len, burst.min(plane_words - j));
                assert!(
                    t < w_planes || (t == w_planes && j + len <= w_issued),
                    "plane {t} words {j}.. read before written ({w_planes} planes, {w_issued} words)"
                );
                asked += len;
            }
            for i in 0..len {
                port.push_back((clock + latency + i, tag << 32 | (addr / 4 + i) as u64));
            }
            old_waiting = false;
            let in_flight = port.iter().filter(|w| w.1 >> 32 == gen).count();
            assert!(
                prefetch.len() + in_flight <= cap,
                "reads beyond the FIFO's room"
            );
        }
        assert!(!u.push.val() || u.rd_en.val());
        if u.rd_en.val() {
            assert!(head.is_some(), "rd_en on an empty read FIFO");
            let data = port.pop_front().unwrap().1;
            if u.push.val() {
                assert_eq!(data >> 32, gen, "a word of a read from before the restart");
                let (t, j) = (pushed / plane_words, pushed % plane_words);
                assert_eq!(data as usize & 0xffff_ffff, ((t % n) << slot_bits) / 4 + j);
                prefetch.push_back(data);
                assert!(prefetch.len() <= cap, "prefetch FIFO overflow");
                pushed += 1;
            } else {
                assert_ne!(data >> 32, gen, "a word of this stream dropped");
                dropped += 1;
            }
        }
        if restart {
            old_waiting = u.waiting.val() && (write_waiting || u.cmd_full.val());
        }
        if rng.gen_range(0..2) == 0 {
            prefetch.pop_front();
        }
        b.tick();
        if issue {
            w_issued = w_next;
            if plane_done {
                (w_planes, w_issued) = (w_planes + 1, 0);
            }
        }
        if restart {
            gen += 1;
            restarted = true;
            (w_planes, w_issued, pushed, asked) = (0, 0, 0, 0);
            prefetch.clear();
        }
    }
    if restart_at.is_some() {
        assert!(dropped > 0, "no read was in flight at the restart");
    }
    assert!(port.iter().all(|w| w.1 >> 32 == gen), "old words left");
}

#[test]
fn read_side_walks_written_planes_in_order() {
    run_read_side(11, 37, 4, 3, 16, None);
    run_read_side(12, 256, 32, 2, 64, None);
    run_read_side(13, 9, 1, 5, 4, None);
}

#[test]
fn read_side_drops_the_reads_in_flight_at_a_restart() {
    for at in [40, 97, 301, 555] {
        run_read_side(20 + at as u64, 37, 4, 3, 16, Some(at));
    }
}
