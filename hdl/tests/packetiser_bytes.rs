//! The packet's read-out, each block against its rule:
//! * the prefix cursor: random starts (1 to 300 bytes after the first),
//!   steps and stalls, starts in the middle of a prefix included: the
//!   index and the last-byte flag every clock against a reference written
//!   from the block's doc, and every prefix read out whole ends on byte
//!   `rest` with `last`, and only there;
//! * the packet CRC: random packets of 0 to 300 bytes added under random
//!   stalls, restarts in the middle of a packet and new packets started on
//!   the CRC's last byte (as after an Overflow packet): the four bytes out
//!   are [`smartagg_model::packet::crc32c`] of the packet's bytes, least
//!   significant first, `tail_last` on the fourth only.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::packetiser::{PacketCrc, PrefixCursor};
use smartagg_hdl::testbench::bench::{settle, Bench};
use smartagg_model::packet::crc32c;

#[test]
fn prefix_cursor_counts_the_bytes_and_flags_the_last() {
    let mut rng = common::rng(44);
    let mut b = Bench::new(PrefixCursor::default(), |u| &mut u.clock);
    // The reference: index, bytes left after this clock's, last (registers
    // power up as 0 in simulation).
    let (mut idx, mut left, mut last) = (0u16, 0u16, false);
    // The prefix being read out whole: its `rest`, if no start cut it.
    let mut whole: Option<u16> = None;
    let (mut starts, mut wholes, mut lasts) = (0, 0, 0);
    for cycle in 0..30_000 {
        let start = rng.gen_bool(0.03);
        let rest = rng.gen_range(1..=300u16);
        let step = rng.gen_bool(0.7);
        let u = &mut b.uut;
        u.start.next = start;
        u.rest.next = (rest as u64).to_bits();
        u.step.next = step;
        settle(u);
        assert_eq!(u.index.val().to_u64(), idx as u64, "cycle {cycle}: index");
        assert_eq!(u.last.val(), last, "cycle {cycle}: last");
        if let Some(r) = whole {
            assert_eq!(
                last,
                idx == r,
                "cycle {cycle}: byte {idx} of a prefix of {}",
                r + 1
            );
            if step && last {
                wholes += 1;
                whole = None;
            }
        }
        lasts += last as usize;
        b.tick();
        if start {
            (idx, left, last) = (0, rest, false);
            whole = Some(rest);
            starts += 1;
        } else if step {
            (idx, left, last) = (idx.wrapping_add(1), left.wrapping_sub(1), left == 1);
        }
    }
    assert!(
        starts > 500 && wholes > 20 && lasts > 20,
        "{starts} starts, {wholes} prefixes read whole, {lasts} clocks on a last byte"
    );
}

#[test]
fn packet_crc_sends_the_models_crc32c_after_the_packet() {
    let mut rng = common::rng(45);
    let mut b = Bench::new(PacketCrc::default(), |u| &mut u.clock);
    let (mut packets, mut cut, mut chained) = (0, 0, 0);
    let mut chain = false;
    for _ in 0..400 {
        let len = rng.gen_range(0..=300usize);
        let msg: Vec<u8> = (0..len).map(|_| rng.gen()).collect();
        // Unless the last packet's fourth CRC byte started this one.
        if !chain {
            let u = &mut b.uut;
            u.start.next = true;
            u.add.next = rng.gen();
            u.tail.next = rng.gen();
            u.data.next = (rng.gen::<u8>() as u64).to_bits();
            b.tick();
        }
        let cut_at = rng.gen_bool(0.1).then(|| rng.gen_range(0..=len));
        let mut sent = 0;
        while sent < len {
            if cut_at == Some(sent) {
                break;
            }
            let add = rng.gen_bool(0.7);
            let u = &mut b.uut;
            u.start.next = false;
            u.add.next = add;
            u.tail.next = false;
            u.data.next = (if add { msg[sent] } else { rng.gen() } as u64).to_bits();
            b.tick();
            sent += add as usize;
        }
        if sent < len {
            // Cut: the next packet starts over.
            cut += 1;
            chain = false;
            continue;
        }
        let want = crc32c(&msg).to_le_bytes().to_vec();
        let mut got = Vec::new();
        chain = rng.gen_bool(0.3);
        while got.len() < 4 {
            let tail = rng.gen_bool(0.8);
            let u = &mut b.uut;
            u.start.next = false;
            u.add.next = false;
            u.tail.next = tail;
            settle(u);
            let last = u.tail_last.val();
            assert_eq!(
                last,
                got.len() == 3,
                "packet {packets}: tail_last at byte {}",
                got.len()
            );
            if tail {
                got.push(u.tail_byte.val().to_u64() as u8);
                u.start.next = chain && last;
            }
            b.tick();
        }
        assert_eq!(got, want, "packet {packets} of {len} bytes");
        packets += 1;
        chained += chain as usize;
    }
    assert!(
        packets > 300 && cut > 20 && chained > 60,
        "{packets} packets, {cut} cut, {chained} chained"
    );
}
