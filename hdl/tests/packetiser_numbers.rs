//! The packetiser's bookkeeping blocks (the packetiser as a whole is
//! checked byte for byte against the model's encoder in `packetiser.rs`):
//! * the sequence numbers: driven record by record as the packetiser
//!   drives them (records taken with losses before them, some dropped for
//!   want of room, Overflow packets announcing what is pending), across the
//!   2³² wrap. Every clock the outputs equal the definition of
//!   `model/PACKETS.md` §5; the packets numbered so, encoded by the model,
//!   decode with every lost record announced on the device and none lost
//!   in transport. Then random commands and restarts, clock by clock;
//! * the packet's lengths: random records of every kind (Blinks with ROIs
//!   of 3×3 to 31×31 and every varint length; the StreamStart of each
//!   shipped design and of the test configuration, from the model's
//!   configuration with that design's kernel), the payload length and the
//!   prefix against the model's packet, and the registered room check at, below and above the bytes
//!   needed (with and without an Overflow packet first).

mod common;

use common::records::{random_blink, random_dropped, random_end};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::config::BackHalfConfig;
use smartagg_hdl::designs::Design;
use smartagg_hdl::packetiser::{PacketLength, SequenceNumbers};
use smartagg_hdl::pipeline::test_back_config;
use smartagg_hdl::testbench::bench::{settle, Bench};
use smartagg_model::config::PipelineConfig;
use smartagg_model::packet::{decode_all, encode_record};
use smartagg_model::record::{OverflowRecord, Record, StreamStart};
use smartagg_model::rice::{encode_counts, varint_len};

/// The definition: the next number, the first pending lost number, the
/// pending count and the sticky flag.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Ledger {
    seq: u32,
    first: u32,
    count: u32,
    overflowed: bool,
}

impl Ledger {
    fn lose(&mut self, n: u32) {
        if n != 0 {
            self.overflowed = true;
            if self.count == 0 {
                self.first = self.seq;
            }
            self.count = self.count.wrapping_add(n);
        }
    }
    fn take(&mut self, lost: u32) {
        self.lose(lost);
        self.seq = self.seq.wrapping_add(lost);
    }
}

/// One clock of `b` with the commands given, then the outputs against `l`.
fn step(b: &mut Bench<SequenceNumbers>, l: &Ledger, what: &str) {
    b.tick();
    let u = &mut b.uut;
    u.take.next = false;
    u.dropped.next = false;
    u.announced.next = false;
    u.advance.next = false;
    u.restart.next = false;
    settle(u);
    let got = Ledger {
        seq: u.seq.val().to_u64() as u32,
        first: u.lost_first.val().to_u64() as u32,
        count: u.lost_count.val().to_u64() as u32,
        overflowed: u.overflowed.val(),
    };
    assert_eq!(got, *l, "after {what}");
    assert_eq!(u.pending.val(), l.count != 0, "after {what}");
}

#[test]
fn sequence_numbers_announce_every_loss_as_the_models_decoder_reads_it() {
    let mut rng = common::rng(71);
    let mut b = Bench::new(SequenceNumbers::default(), |u| &mut u.clock);
    // The decoder expects 0 first; large losses carry the numbers across
    // the wrap.
    let init = 0;
    let mut l = Ledger {
        seq: init,
        ..Default::default()
    };
    b.uut.seq_init.next = (init as u64).to_bits();
    b.uut.restart.next = true;
    // The first pending number is not part of a restart (nothing reads it
    // until a loss sets it): start the definition from the block's.
    b.tick();
    settle(&mut b.uut);
    l.first = b.uut.lost_first.val().to_u64() as u32;
    step(&mut b, &l, "the restart");

    let (mut stream, mut lost_total, mut announced) = (Vec::new(), 0u64, 0);
    let (mut queue_losses, mut drops, mut mixed, mut wraps) = (0, 0, 0, 0);
    for rec in 0..3000 {
        // The record taken, with the records lost before it.
        let lost: u32 = match (rec, rng.gen_range(0..100)) {
            (0, _) => 0,
            (_, 0) => rng.gen_range(1 << 20..1 << 30),
            (_, 1..=9) => rng.gen_range(1..4),
            _ => 0,
        };
        queue_losses += (lost != 0) as usize;
        lost_total += lost as u64;
        b.uut.take.next = true;
        b.uut.lost.next = (lost as u64).to_bits();
        let before = l.seq;
        l.take(lost);
        wraps += (l.seq < before) as usize;
        step(&mut b, &l, &format!("record {rec} taken"));
        // Random lost values on the other clocks: only `take` reads them.
        b.uut.lost.next = (rng.gen::<u32>() as u64).to_bits();
        if rec > 0 && rng.gen_bool(0.1) {
            // No room: dropped, and its number consumed.
            mixed += (l.count != 0) as usize;
            b.uut.dropped.next = true;
            l.lose(1);
            step(&mut b, &l, &format!("record {rec} dropped"));
            drops += 1;
            lost_total += 1;
        } else {
            if b.uut.pending.val() {
                let first = b.uut.lost_first.val().to_u64() as u32;
                let count = b.uut.lost_count.val().to_u64() as u32;
                let ovf = Record::Overflow(OverflowRecord {
                    first_seq: first,
                    count,
                });
                encode_record(&ovf, first, &mut stream).unwrap();
                b.uut.announced.next = true;
                l.count = 0;
                step(&mut b, &l, &format!("record {rec}'s Overflow packet"));
                announced += 1;
            }
            let seq = b.uut.seq.val().to_u64() as u32;
            let rec = Record::Dropped(random_dropped(&mut rng));
            encode_record(&rec, seq, &mut stream).unwrap();
        }
        b.uut.advance.next = true;
        l.seq = l.seq.wrapping_add(1);
        wraps += (l.seq == 0) as usize;
        step(&mut b, &l, &format!("record {rec} done"));
    }
    let decoded = decode_all(&stream);
    let s = &decoded.stats;
    assert_eq!(s.lost_in_transport, 0, "{s:?}");
    assert_eq!(s.out_of_order, 0, "{s:?}");
    // The losses still pending after the last record are not in the stream.
    let pending = b.uut.lost_count.val().to_u64();
    assert_eq!(s.lost_on_device + pending, lost_total, "{s:?}");
    assert_eq!(s.packets_ok as usize, 3000 - drops + announced);
    // The numbers wrapped, both kinds of loss were announced, some in one
    // Overflow record.
    assert!(
        wraps >= 2 && queue_losses > 200 && drops > 200 && mixed > 20 && announced > 300,
        "{wraps} wraps, {queue_losses} queue losses, {drops} drops, {mixed} mixed, \
         {announced} announced"
    );

    // Random commands (one a clock, or none) and restarts.
    let mut restarts = 0;
    for clock in 0..20_000 {
        let u = &mut b.uut;
        let what = match rng.gen_range(0..100) {
            0..=1 => {
                let init: u32 = rng.gen();
                u.seq_init.next = (init as u64).to_bits();
                u.restart.next = true;
                l.seq = init;
                l.count = 0;
                l.overflowed = false;
                restarts += 1;
                "restart"
            }
            2..=29 => {
                let lost = if rng.gen_bool(0.5) { 0 } else { rng.gen() };
                u.take.next = true;
                u.lost.next = (lost as u64).to_bits();
                l.take(lost);
                "take"
            }
            30..=44 => {
                u.dropped.next = true;
                l.lose(1);
                "drop"
            }
            45..=54 => {
                u.announced.next = true;
                l.count = 0;
                "announce"
            }
            55..=79 => {
                u.advance.next = true;
                l.seq = l.seq.wrapping_add(1);
                "advance"
            }
            _ => "nothing",
        };
        step(&mut b, &l, &format!("clock {clock}: {what}"));
    }
    assert!(restarts > 300, "{restarts} restarts");
}

/// A record of `kind` (0 `start`, 1 Blink, 2 Dropped, 3 StreamEnd): the
/// record, and for a Blink the bytes of its base's varint and of its codes.
fn record(rng: &mut ChaCha8Rng, kind: u64, start: &StreamStart) -> (Record, usize, usize) {
    match kind {
        0 => (Record::Start(start.clone()), 0, 0),
        1 => {
            let r = 2 * rng.gen_range(1..=15) + 1;
            let mut blink = random_blink(rng, r);
            // Bases of every varint length (1 to 5 bytes), offsets of any size.
            let base: u32 = rng.gen::<u32>() >> rng.gen_range(0..32);
            let spread: u32 = rng.gen::<u32>() >> rng.gen_range(0..32);
            blink.counts = (0..r * r)
                .map(|_| base.saturating_add(rng.gen_range(0..=spread)))
                .collect();
            let base = *blink.counts.iter().min().unwrap();
            let mut block = Vec::new();
            encode_counts(&blink.counts, &mut block);
            let v = varint_len(base);
            (Record::Blink(blink), v, block.len() - v - 1)
        }
        2 => (Record::Dropped(random_dropped(rng)), 0, 0),
        _ => (Record::End(random_end(rng)), 0, 0),
    }
}

#[test]
fn packet_lengths_are_the_models_and_the_room_check_is_exact() {
    let mut rng = common::rng(72);
    let mut ovf = Vec::new();
    let overflow = Record::Overflow(OverflowRecord {
        first_seq: 5,
        count: 1,
    });
    encode_record(&overflow, 5, &mut ovf).unwrap();
    let (mut varints, mut rooms, mut no_rooms) = ([0; 6], 0, 0);
    let mut configs: Vec<(String, BackHalfConfig)> = Design::all()
        .unwrap()
        .into_iter()
        .map(|d| (d.name(), d.config))
        .collect();
    configs.push(("test".into(), test_back_config(4, 3, 1).unwrap()));
    for (name, cfg) in &configs {
        // The design's StreamStart, as the model's configuration with its
        // kernel announces it; the block sized by the gateware's own count.
        let f = &cfg.front;
        let start = PipelineConfig::new(
            f.width,
            f.height,
            f.n_max,
            f.kernel.clone(),
            f.kernel_shift,
            1,
        )
        .stream_start();
        let mut b = Bench::new(PacketLength::new(cfg.stream_start_bytes()), |u| {
            &mut u.clock
        });
        for i in 0..600 {
            let kind = i % 4;
            let (rec, v, code_bytes) = record(&mut rng, kind, &start);
            let mut packet = Vec::new();
            encode_record(&rec, rng.gen(), &mut packet).unwrap();
            varints[v] += 1;
            let pending = rng.gen_bool(0.3);
            let need = packet.len() + if pending { ovf.len() } else { 0 };
            let free = match rng.gen_range(0..4) {
                0 => need - 1,
                1 => need,
                2 => need + 1,
                _ => rng.gen_range(0..need * 2),
            };
            let u = &mut b.uut;
            u.kind.next = kind.to_bits();
            u.varint_len.next = (v as u64).to_bits();
            u.code_bytes.next = (code_bytes as u64).to_bits();
            u.pending.next = pending;
            u.fifo_free.next = (free as u64).to_bits();
            // Decide's first clock: the room check is being made.
            u.decide.next = true;
            settle(u);
            let what = format!("{name}, record {i} ({kind}): {rec:?}");
            assert_eq!(
                u.payload_len.val().to_u64() as usize,
                packet.len() - 14,
                "{what}"
            );
            // The prefix: all but the codes and the CRC.
            assert_eq!(
                u.prefix_rest.val().to_u64() as usize + 1,
                packet.len() - 4 - code_bytes,
                "{what}"
            );
            b.tick();
            // Decide's second clock: the check speaks of this record, as the
            // FIFO's room was last clock (it is a register).
            b.uut.fifo_free.next = rng.gen::<u16>().to_bits();
            settle(&mut b.uut);
            assert!(b.uut.ready.val(), "{what}");
            assert_eq!(b.uut.room.val(), free >= need, "{what}: {free} free");
            rooms += (free == need) as usize;
            no_rooms += (free + 1 == need) as usize;
            // Out of Decide: not ready the clock after.
            b.uut.decide.next = false;
            b.tick();
            settle(&mut b.uut);
            assert!(!b.uut.ready.val(), "{what}");
        }
    }
    assert!(
        varints[1..].iter().all(|&n| n > 20) && rooms > 200 && no_rooms > 200,
        "varints {varints:?}, exactly room {rooms}, one byte short {no_rooms}"
    );
}
