//! The packetiser's sub-blocks, each against its definition or the model
//! (the packetiser as a whole is checked byte for byte against the model's
//! encoder in `packetiser.rs`):
//! * the CRC-32C step: every byte from random and extreme registers against
//!   the bitwise reflected CRC, and random messages chained through it
//!   against [`smartagg_model::packet::crc32c`];
//! * the prefix bytes: random loads and read-outs, byte `index` of the
//!   last load (0 past the last byte, 0 when not read);
//! * the count block's head: random ROIs, the model's base varint and k
//!   ([`smartagg_model::rice::encode_counts`]) for varints of 1 to 5 bytes;
//! * the Rice lengths: every k for offsets of every magnitude against
//!   [`smartagg_model::rice::code_len`];
//! * the Rice choice: random ROIs fed as pass 2 does (gaps included), the
//!   model's k and the bytes of its codes after the scan;
//! * the Rice code: the codes of random ROIs with the model's k, packed MSB
//!   first, against the model's count block bit for bit;
//! * the code pipeline: random ROIs as the packetiser feeds them (pass 2's
//!   offsets, then the codes under random gaps, stalls and restarts), the
//!   model's count block bit for bit, one code a clock when nothing stalls;
//! * the count streamer: random ROIs (anchors on every row, half of them at
//!   the sensor's edges), random grant delays and takes, random data on the read
//!   port between rows: every count in row-major order (0 off the sensor),
//!   each row's address, the mask flag of each row on the sensor;
//! * the bit packer: random codes of 1 to 64 bits under the packetiser's
//!   command rule, every byte out against the bits in, MSB first, the last
//!   one zero-padded.
//!
//! The widths are the shipped designs' (RCW = 17; 69 and 61 prefix bytes)
//! and the widest (RCW = 32).

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::config::BackHalfConfig;
use smartagg_hdl::packetiser::{
    rice_candidates, BitPacker, CodePipeline, CountBlockHead, CountStreamer, Crc32cStep,
    PrefixBytes, RiceChoice, RiceCode, RiceLengths, HEAD_BYTES,
};
use smartagg_hdl::pipeline::{spcimager150_back_config, test_back_config};
use smartagg_hdl::testbench::bench::{settle, Bench};
use smartagg_model::packet::crc32c;
use smartagg_model::rice::{choose, code_len, encode_counts, varint_len};

/// A random value below 2^bits, of a random magnitude (log-uniform bits).
fn magnitude(rng: &mut impl Rng, bits: u32) -> u64 {
    let b = rng.gen_range(0..=bits);
    if b == 0 {
        0
    } else {
        rng.gen_range(0..1u64 << b)
    }
}

/// A random ROI of `r`² counts below 2^bits: a base and a spread of random
/// magnitudes, and with probability `p_far` one count at the top (an
/// escape code among regular ones).
fn random_roi(rng: &mut impl Rng, r: usize, bits: u32, p_far: f64) -> Vec<u32> {
    let top = (1u64 << bits) - 1;
    let base = magnitude(rng, bits);
    let spread = magnitude(rng, bits);
    let mut counts: Vec<u32> = (0..r * r)
        .map(|_| (base + rng.gen_range(0..=spread)).min(top) as u32)
        .collect();
    if rng.gen_bool(p_far) {
        counts[rng.gen_range(0..r * r)] = top as u32;
    }
    counts
}

/// The reflected CRC-32C register after one byte, bit by bit.
fn crc_byte(crc: u32, byte: u8) -> u32 {
    let mut c = crc ^ byte as u32;
    for _ in 0..8 {
        c = if c & 1 != 0 {
            (c >> 1) ^ 0x82F6_3B78
        } else {
            c >> 1
        };
    }
    c
}

#[test]
fn crc32c_step_is_the_bitwise_crc_and_chains_to_the_models() {
    let mut rng = common::rng(21);
    let mut u = Crc32cStep::default();
    u.connect_all();
    check_all(&u).expect("rust-hdl design checks");
    let step = |u: &mut Crc32cStep, crc: u32, byte: u8| {
        u.crc.next = (crc as u64).to_bits();
        u.data.next = (byte as u64).to_bits();
        settle(u);
        u.updated.val().to_u64() as u32
    };
    for crc in [0, u32::MAX, 0x8000_0001]
        .into_iter()
        .chain((0..40).map(|_| rng.gen()))
    {
        for byte in 0..=255u8 {
            assert_eq!(
                step(&mut u, crc, byte),
                crc_byte(crc, byte),
                "crc {crc:#x}, byte {byte:#x}"
            );
        }
    }
    for len in [0, 1, 2, 3, 17, 69, 300] {
        let msg: Vec<u8> = (0..len).map(|_| rng.gen()).collect();
        let crc = msg.iter().fold(u32::MAX, |c, &b| step(&mut u, c, b));
        assert_eq!(!crc, crc32c(&msg), "{len}-byte message");
    }
}

fn prefix_case(bytes: usize, seed: u64) {
    let mut rng = common::rng(seed);
    let mut b = Bench::new(PrefixBytes::new(bytes), |u| &mut u.clock);
    let leaves = bytes.next_power_of_two();
    // Registers power up as 0 in simulation.
    let mut regs = vec![0u8; bytes];
    let (mut loads, mut nonzero) = (0, 0);
    for cycle in 0..3000 {
        let load = rng.gen_bool(0.1);
        let d: Vec<u8> = (0..bytes).map(|_| rng.gen()).collect();
        let read = rng.gen_bool(0.8);
        let index = rng.gen_range(0..leaves);
        let u = &mut b.uut;
        u.load.next = load;
        for (s, &v) in u.d.iter_mut().zip(&d) {
            s.next = (v as u64).to_bits();
        }
        u.read.next = read;
        u.index.next = (index as u64).to_bits();
        settle(u);
        let want = if read && index < bytes {
            regs[index]
        } else {
            0
        };
        assert_eq!(
            u.selected.val().to_u64(),
            want as u64,
            "cycle {cycle}: byte {index} of {bytes} (read {read})"
        );
        nonzero += (want != 0) as usize;
        b.tick();
        if load {
            regs = d;
            loads += 1;
        }
    }
    assert!(
        loads > 200 && nonzero > 1000,
        "{loads} loads, {nonzero} bytes"
    );
}

#[test]
fn prefix_bytes_read_out_the_last_load_byte_by_byte() {
    for (bytes, seed) in [(69, 1), (61, 2), (18, 3), (1, 4)] {
        prefix_case(bytes, seed);
    }
}

/// Random ROIs of `r`² counts below 2^RCW: the block's head bytes after
/// a clock are the model's count block up to and including k.
fn head_case<const RCW: usize>(r: usize, seed: u64) {
    let mut rng = common::rng(seed);
    let mut b = Bench::new(CountBlockHead::<RCW>::default(), |u| &mut u.clock);
    let mut by_len = [0usize; 6];
    for roi in 0..600 {
        let counts = random_roi(&mut rng, r, RCW as u32, 0.0);
        let (base, k, _) = choose(&counts);
        let mut block = Vec::new();
        encode_counts(&counts, &mut block);
        let u = &mut b.uut;
        u.base.next = (base as u64).to_bits();
        u.k.next = (k as u64).to_bits();
        b.tick();
        settle(&mut b.uut);
        let u = &b.uut;
        let n = varint_len(base);
        assert_eq!(
            u.varint_len.val().to_u64(),
            n as u64,
            "ROI {roi}: base {base}"
        );
        let got: Vec<u8> = u.bytes.iter().map(|s| s.val().to_u64() as u8).collect();
        assert_eq!(got[..=n], block[..=n], "ROI {roi}: base {base}, k {k}");
        assert!(got[n + 1..].iter().all(|&v| v == 0), "ROI {roi}: {got:?}");
        by_len[n] += 1;
    }
    // Every varint length the width allows (1 + ⌊(RCW − 1) / 7⌋ bytes).
    let longest = (RCW - 1) / 7 + 1;
    assert!(
        (1..=longest).all(|n| by_len[n] > 10),
        "varint lengths seen {by_len:?}"
    );
    assert_eq!(HEAD_BYTES, 6);
}

#[test]
fn count_block_head_is_the_models_base_varint_and_k() {
    head_case::<17>(9, 11);
    head_case::<32>(3, 12);
}

fn lengths_case<const RCW: usize>(seed: u64) {
    let mut rng = common::rng(seed);
    let kn = rice_candidates(RCW);
    let mut u = RiceLengths::<RCW>::new(kn);
    u.connect_all();
    check_all(&u).expect("rust-hdl design checks");
    let top = (1u64 << RCW) - 1;
    let mut escapes = 0;
    for i in 0..3000 {
        let d = match i {
            0 => 0,
            1 => top,
            _ => magnitude(&mut rng, RCW as u32),
        } as u32;
        u.offset.next = (d as u64).to_bits();
        settle(&mut u);
        for k in 0..kn {
            let want = code_len(d, k as u8);
            assert_eq!(
                u.extra[k].val().to_u64() + 1 + k as u64,
                want as u64,
                "d {d}, k {k}"
            );
            escapes += (want == 64) as usize;
        }
    }
    assert!(escapes > 1000, "{escapes} escapes");
}

#[test]
fn rice_lengths_are_the_models_code_lengths_for_every_k() {
    lengths_case::<17>(31);
    lengths_case::<32>(32);
}

/// Random ROIs: the block's codes for the model's k, packed MSB first and
/// zero-padded, are the model's count block after its head.
fn code_case<const RCW: usize>(r: usize, seed: u64) {
    let mut rng = common::rng(seed);
    let mut b = Bench::new(RiceCode::<RCW>::default(), |u| &mut u.clock);
    let (mut escapes, mut ks) = (0, std::collections::BTreeSet::new());
    for roi in 0..300 {
        let counts = random_roi(&mut rng, r, RCW as u32, 0.3);
        let (base, k, _) = choose(&counts);
        assert!((k as usize) < rice_candidates(RCW));
        let mut block = Vec::new();
        encode_counts(&counts, &mut block);
        let codes = &block[varint_len(base) + 1..];
        // The masks are registers of k: a clock after k is set.
        b.uut.k.next = (k as u64).to_bits();
        b.tick();
        let mut bits: Vec<bool> = Vec::new();
        for &c in &counts {
            let d = c - base;
            let u = &mut b.uut;
            u.quotient.next = ((d >> k) as u64).to_bits();
            u.offset.next = (d as u64).to_bits();
            settle(u);
            let len = u.len.val().to_u64() as u32;
            assert_eq!(len, code_len(d, k), "ROI {roi}: d {d}, k {k}");
            let code = u.code.val().to_u64();
            assert!(
                len == 64 || code >> len == 0,
                "ROI {roi}: bits above the code"
            );
            bits.extend((0..len).rev().map(|i| code >> i & 1 == 1));
            escapes += (len == 64) as usize;
        }
        assert_eq!(pack_bits(&bits), codes, "ROI {roi}: base {base}, k {k}");
        ks.insert(k);
    }
    assert!(escapes > 20 && ks.len() > 8, "{escapes} escapes, k {ks:?}");
}

#[test]
fn rice_codes_pack_into_the_models_count_block() {
    code_case::<17>(9, 41);
    code_case::<32>(3, 42);
}

/// Bits of codes, MSB first, packed into bytes (the last one zero-padded).
fn pack_bits(bits: &[bool]) -> Vec<u8> {
    bits.chunks(8)
        .map(|c| {
            (0..8).fold(0u8, |a, i| {
                a << 1 | c.get(i).copied().unwrap_or(false) as u8
            })
        })
        .collect()
}

/// Random ROIs through the code pipeline as the packetiser drives it: pass
/// 2 (the offsets stop in stage A), a few clocks of neither, then Codes
/// with the count streamer's gaps and the bit packer's stalls at random,
/// and now and then a restart with codes in flight.
fn code_pipeline_case<const RCW: usize>(r: usize, seed: u64) {
    let mut rng = common::rng(seed);
    let mut b = Bench::new(CodePipeline::<RCW>::default(), |u| &mut u.clock);
    let (mut restarts, mut stalled) = (0, 0);
    for roi in 0..120 {
        let counts = random_roi(&mut rng, r, RCW as u32, 0.3);
        let (base, k, _) = choose(&counts);
        let mut block = Vec::new();
        encode_counts(&counts, &mut block);
        let codes = &block[varint_len(base) + 1..];
        let full_speed = roi % 4 == 0;
        // Pass 2: every count is taken; its offset passes through A, in order.
        b.uut.base.next = (base as u64).to_bits();
        b.uut.pass2.next = true;
        let (mut next, mut offsets) = (0, Vec::new());
        while offsets.len() < counts.len() {
            let u = &mut b.uut;
            let valid = next < counts.len() && (full_speed || rng.gen_bool(0.7));
            u.count_valid.next = valid;
            u.count.next = (*counts.get(next).unwrap_or(&0) as u64).to_bits();
            u.code_taken.next = rng.gen_bool(0.5);
            settle(u);
            assert!(u.ready.val(), "ROI {roi}: pass 2 stalls");
            assert!(
                !u.b_valid.val() && !u.c_valid.val(),
                "ROI {roi}: pass 2 past A"
            );
            if u.a_valid.val() {
                offsets.push(u.a_offset.val().to_u64() as u32);
            }
            next += valid as usize;
            b.tick();
            assert!(b.cycles < 1_000_000);
        }
        let want: Vec<u32> = counts.iter().map(|c| c - base).collect();
        assert_eq!(offsets, want, "ROI {roi}: pass 2's offsets");
        // Choose, Decide, Emit: nothing enters; k is set.
        b.uut.pass2.next = false;
        b.uut.k.next = (k as u64).to_bits();
        for _ in 0..3 {
            b.uut.count_valid.next = rng.gen_bool(0.5);
            b.tick();
            let u = &mut b.uut;
            assert!(!u.a_valid.val() && !u.b_valid.val() && !u.c_valid.val());
        }
        // Codes.
        b.uut.codes.next = true;
        let restart_at = rng
            .gen_bool(0.15)
            .then(|| rng.gen_range(2..counts.len() + 3));
        let (mut next, mut bits, mut clocks, mut restarted) = (0, Vec::new(), 0, false);
        loop {
            let u = &mut b.uut;
            let valid = next < counts.len() && (full_speed || rng.gen_bool(0.8));
            u.count_valid.next = valid;
            u.count.next = (*counts.get(next).unwrap_or(&0) as u64).to_bits();
            let taken = full_speed || rng.gen_bool(0.7);
            u.code_taken.next = taken;
            settle(u);
            let (busy, c_valid) = (u.a_valid.val() | u.b_valid.val(), u.c_valid.val());
            if next == counts.len() && !busy && !c_valid {
                break;
            }
            if c_valid && taken {
                let len = u.len.val().to_u64() as u32;
                let code = u.code.val().to_u64();
                bits.extend((0..len).rev().map(|i| code >> i & 1 == 1));
            }
            stalled += (c_valid && !taken) as usize;
            if valid && u.ready.val() {
                next += 1;
            }
            if restart_at == Some(clocks) {
                b.uut.restart.next = true;
                b.tick();
                b.uut.restart.next = false;
                let u = &mut b.uut;
                settle(u);
                assert!(!u.a_valid.val() && !u.b_valid.val() && !u.c_valid.val());
                restarts += 1;
                restarted = true;
                break;
            }
            b.tick();
            clocks += 1;
            assert!(clocks < 100_000, "ROI {roi}: the codes never came out");
        }
        b.uut.codes.next = false;
        if restarted {
            continue;
        }
        assert_eq!(pack_bits(&bits), codes, "ROI {roi}: base {base}, k {k}");
        if full_speed {
            // One count a clock: the last code leaves three clocks after the last count.
            assert_eq!(clocks, counts.len() + 3, "ROI {roi}: bubbles");
        }
    }
    assert!(
        restarts > 5 && stalled > 100,
        "{restarts} restarts, {stalled} stalls"
    );
}

#[test]
fn code_pipeline_makes_the_models_codes_under_stalls_and_restarts() {
    code_pipeline_case::<17>(9, 51);
    code_pipeline_case::<32>(3, 52);
}

/// Random codes through the packer under the packetiser's rule (a byte out
/// while one is whole, else a code in, else the pad), against a queue of
/// bits by definition.
#[test]
fn bit_packer_sends_the_codes_bits_msb_first_then_pads() {
    let mut rng = common::rng(51);
    let mut b = Bench::new(BitPacker::default(), |u| &mut u.clock);
    b.uut.start.next = true;
    b.tick();
    b.uut.start.next = false;
    let mut queue: std::collections::VecDeque<bool> = Default::default();
    let (mut sent, mut padded, mut appended) = (0usize, 0usize, 0usize);
    for cycle in 0..20_000 {
        let u = &mut b.uut;
        settle(u);
        let nb = queue.len();
        assert_eq!(u.full.val(), nb >= 8, "cycle {cycle}: {nb} bits wait");
        assert_eq!(u.empty.val(), nb == 0, "cycle {cycle}");
        let byte = (0..8).fold(0u64, |a, i| {
            a << 1 | queue.get(i).copied().unwrap_or(false) as u64
        });
        if nb > 0 {
            assert_eq!(
                u.next_byte.val().to_u64(),
                byte,
                "cycle {cycle}: {nb} bits wait"
            );
        }
        let (mut send, mut append, mut pad) = (false, false, false);
        let (mut code, mut len) = (0u64, 0usize);
        if nb >= 8 {
            send = true;
            queue.drain(..8);
            sent += 1;
        } else if rng.gen_bool(0.9) {
            append = true;
            len = rng.gen_range(1..=64);
            code = rng.gen::<u64>() >> (64 - len);
            queue.extend((0..len).rev().map(|i| code >> i & 1 == 1));
            appended += 1;
        } else if nb > 0 {
            pad = true;
            queue.clear();
            padded += 1;
        }
        u.send.next = send;
        u.append.next = append;
        u.pad.next = pad;
        u.code.next = code.to_bits();
        u.len.next = (len as u64).to_bits();
        b.tick();
    }
    assert!(
        sent > 10_000 && padded > 200 && appended > 3000,
        "{sent} sent, {padded} padded, {appended} appended"
    );
}

/// Random ROIs of a configuration streamed from a random counter memory
/// (RCW = 17, 64 banks): the counts taken, the rows' addresses and mask
/// flags, against the memory by definition.
fn streamer_case(cfg: &BackHalfConfig, seed: u64) {
    const BANKS: usize = 64;
    let (r, h) = (cfg.roi_size, cfg.front.height as i64);
    let mut rng = common::rng(seed);
    let mut b = Bench::new(CountStreamer::<17, 12, 6>::new(cfg), |u| &mut u.clock);
    let mem: Vec<Vec<(Vec<u64>, bool)>> = (0..BANKS)
        .map(|_| {
            (0..r)
                .map(|_| {
                    let row = (0..r).map(|_| rng.gen_range(1..1u64 << 17)).collect();
                    (row, rng.gen_bool(0.3))
                })
                .collect()
        })
        .collect();
    let (mut off_sensor, mut masked_seen) = (0usize, 0usize);
    for roi in 0..150 {
        let bank = rng.gen_range(0..BANKS);
        // Half the anchors at the sensor's edges, where ROI rows fall off it.
        let ay = if rng.gen_bool(0.5) {
            rng.gen_range(0..h)
        } else {
            [0, 1, h - 2, h - 1][rng.gen_range(0..4)]
        };
        let on = |dy: usize| (0..h).contains(&(ay - (r / 2) as i64 + dy as i64));
        let want: Vec<u64> = (0..r * r)
            .map(|i| {
                if on(i / r) {
                    mem[bank][i / r].0[i % r]
                } else {
                    0
                }
            })
            .collect();
        let want_masked = (0..r).filter(|&dy| on(dy) && mem[bank][dy].1).count();
        off_sensor += (0..r).filter(|&dy| !on(dy)).count();
        let u = &mut b.uut;
        u.bank.next = (bank as u64).to_bits();
        u.anchor_row.next = (ay as u64).to_bits();
        u.start.next = true;
        b.tick();
        b.uut.start.next = false;
        let (mut got, mut masked, mut arriving) = (Vec::new(), 0usize, None::<usize>);
        for cycle in 0.. {
            assert!(cycle < 50 * r * r, "ROI {roi}: the streamer hangs");
            let u = &mut b.uut;
            // The row granted last clock is on the read port; any other
            // clock carries noise.
            let (counts, flag) = match arriving {
                Some(dy) => mem[bank][dy].clone(),
                None => (
                    (0..r).map(|_| rng.gen_range(0..1u64 << 17)).collect(),
                    rng.gen(),
                ),
            };
            for (s, &c) in u.rd_counts.iter_mut().zip(&counts) {
                s.next = c.to_bits();
            }
            u.rd_masked.next = flag;
            let grant = rng.gen_bool(0.4);
            let take = rng.gen_bool(0.7);
            u.rd_grant.next = grant;
            u.take.next = take;
            settle(u);
            if !u.active.val() {
                break;
            }
            if u.masked_row.val() {
                let dy = arriving.expect("a mask flag without a row");
                assert!(on(dy) && mem[bank][dy].1, "ROI {roi}: row {dy} flagged");
                masked += 1;
            }
            if u.valid.val() && take {
                got.push(u.count.val().to_u64());
            }
            arriving = None;
            if u.rd_req.val() && grant {
                let dy = got.len() / r;
                assert_eq!(
                    u.rd_addr.val().to_u64(),
                    (bank * r + dy) as u64,
                    "ROI {roi}: row {dy}'s address"
                );
                arriving = Some(dy);
            }
            b.tick();
        }
        assert_eq!(got, want, "ROI {roi}: bank {bank}, anchor row {ay}");
        assert_eq!(masked, want_masked, "ROI {roi}: masked rows");
        masked_seen += masked;
    }
    assert!(
        off_sensor > 50 && masked_seen > 50,
        "{off_sensor} {masked_seen}"
    );
}

#[test]
fn count_streamer_gives_the_rois_counts_in_order_zero_off_the_sensor() {
    streamer_case(&test_back_config(4, 3, 1).unwrap(), 61);
    streamer_case(&spcimager150_back_config().unwrap(), 62);
}

/// Random ROIs of side `r` through pass 2 (an offset a clock, with gaps)
/// and the scan: the chosen k and its code bytes are the model's.
fn choice_case<const RCW: usize>(r: usize, seed: u64) {
    let mut rng = common::rng(seed);
    let kn = rice_candidates(RCW);
    let mut b = Bench::new(RiceChoice::<RCW>::new(kn, r), |u| &mut u.clock);
    let top = (1u64 << RCW) - 1;
    let mut ks = std::collections::BTreeSet::new();
    for roi in 0..200 {
        let counts = random_roi(&mut rng, r, RCW as u32, 0.2);
        let (base, k, bits) = choose(&counts);
        b.uut.clear.next = true;
        b.tick();
        b.uut.clear.next = false;
        let mut offsets = counts.iter().map(|&c| c - base);
        let mut left = counts.len();
        while left > 0 {
            let valid = rng.gen_bool(0.7);
            let d = if valid {
                left -= 1;
                offsets.next().unwrap()
            } else {
                rng.gen::<u32>() & top as u32
            };
            b.uut.offset.next = (d as u64).to_bits();
            b.uut.offset_valid.next = valid;
            b.tick();
        }
        b.uut.offset_valid.next = false;
        // Stage L, then the add.
        b.tick();
        b.tick();
        b.uut.start_scan.next = true;
        b.tick();
        b.uut.start_scan.next = false;
        b.uut.step.next = true;
        for scan in 0..kn {
            settle(&mut b.uut);
            assert_eq!(b.uut.last.val(), scan == kn - 1, "ROI {roi}: scan {scan}");
            b.tick();
        }
        b.uut.step.next = false;
        settle(&mut b.uut);
        assert_eq!(b.uut.k.val().to_u64(), k as u64, "ROI {roi}: {counts:?}");
        assert_eq!(
            b.uut.code_bytes.val().to_u64(),
            bits.div_ceil(8),
            "ROI {roi}: k {k}, {bits} bits"
        );
        ks.insert(k);
    }
    assert!(ks.len() > 8, "k seen {ks:?}");
}

#[test]
fn rice_choice_is_the_models_k_and_code_bytes() {
    choice_case::<17>(9, 71);
    choice_case::<17>(31, 72);
    choice_case::<32>(3, 73);
}
