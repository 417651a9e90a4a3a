//! The packetiser's record prefix (`hdl/src/packetiser/record_prefix.rs`)
//! against the model's encoder: for random records of every kind (random
//! registers in the StreamStart, two kernels), its lanes are the first
//! bytes of [`smartagg_model::packet::encode_record`]'s packet — header and
//! fixed payload, a Blink's up to its count block's head — and 0 after
//! them; the Overflow lanes are an Overflow packet's header and payload;
//! every lane is 0 when not enabled.

mod common;

use common::records::{random_blink, random_dropped, random_end};

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::config::{BackHalfConfig, GatewareConfig};
use smartagg_hdl::packetiser::RecordPrefix;
use smartagg_hdl::testbench::bench::settle;
use smartagg_model::config::PipelineConfig;
use smartagg_model::packet::encode_record;
use smartagg_model::record::{flags, OverflowRecord, Record, MAX_PLANE};

const NW: usize = 8;

fn config(kernel: &[u32], r: usize) -> (PipelineConfig, BackHalfConfig) {
    let mut cfg = PipelineConfig::new(320, 240, 200, kernel.to_vec(), 8, 1_234_567);
    cfg.slots = 32;
    cfg.roi_size = r;
    cfg.r_assoc = 1;
    let front = GatewareConfig::new(&cfg, 16, 200).unwrap();
    assert_eq!(front.count_bits(), NW);
    let bh = BackHalfConfig::new(&cfg, front, (1 << 31) - 1).unwrap();
    (cfg, bh)
}

fn random_record(rng: &mut ChaCha8Rng, cfg: &PipelineConfig, kind: usize) -> Record {
    let r = cfg.roi_size;
    match kind {
        0 => {
            let mut s = cfg.stream_start();
            s.n_window = rng.gen_range(1..=200);
            s.threshold_int = rng.gen();
            s.threshold_hold = rng.gen();
            s.end_trim = Some(rng.gen_range(0..s.n_window));
            s.l_min = rng.gen();
            s.l_max = rng.gen();
            s.plane_period_ns = rng.gen();
            s.masked_pixels = rng.gen();
            Record::Start(s)
        }
        1 => {
            let mut b = random_blink(rng, r);
            // Anchors anywhere in their 16 bits (the lanes' high bytes).
            (b.anchor_x, b.anchor_y) = (rng.gen(), rng.gen());
            Record::Blink(b)
        }
        2 => Record::Dropped(random_dropped(rng)),
        _ => Record::End(random_end(rng)),
    }
}

/// Drives the block's inputs with `record`, `seq`, the packet's payload
/// length and (a Blink) its count block's head; random values on every
/// input the kind does not use. Returns the prefix the lanes must hold.
fn drive(
    u: &mut RecordPrefix<NW>,
    rng: &mut impl Rng,
    record: &Record,
    seq: u32,
    packet: &[u8],
) -> Vec<u8> {
    u.kind.next = 0.into();
    u.seq.next = (seq as u64).to_bits();
    u.payload_len.next = (u16::from_le_bytes([packet[8], packet[9]]) as u64).to_bits();
    u.slot.next = (rng.gen::<u8>() as u64).to_bits();
    u.flags.next = (rng.gen::<u8>() as u64).to_bits();
    u.masked.next = rng.gen();
    u.ax.next = (rng.gen::<u16>() as u64).to_bits();
    u.ay.next = (rng.gen::<u16>() as u64).to_bits();
    u.t0.next = rng.gen_range(0..=MAX_PLANE).to_bits();
    u.t1.next = rng.gen_range(0..=MAX_PLANE).to_bits();
    u.ts.next = rng.gen_range(0..=MAX_PLANE).to_bits();
    u.te.next = rng.gen_range(0..=MAX_PLANE).to_bits();
    u.planes.next = (rng.gen::<u32>() as u64).to_bits();
    for h in u.head.iter_mut() {
        h.next = (rng.gen::<u8>() as u64).to_bits();
    }
    u.settings.n_window.next = (rng.gen::<u8>() as u64).to_bits();
    u.settings.end_trim.next = (rng.gen::<u8>() as u64).to_bits();
    for s in [
        &mut u.settings.threshold,
        &mut u.settings.threshold_hold,
        &mut u.settings.l_min,
        &mut u.settings.l_max,
        &mut u.settings.plane_period,
        &mut u.settings.masked_pixels,
        &mut u.lost_first,
        &mut u.lost_count,
    ] {
        s.next = (rng.gen::<u32>() as u64).to_bits();
    }
    for s in [
        &mut u.c_planes,
        &mut u.totals.blinks,
        &mut u.totals.unconfirmed,
        &mut u.totals.dropped,
        &mut u.totals.bridged,
        &mut u.totals.cuts,
    ] {
        s.next = rng.gen::<u64>().to_bits();
    }
    let prefix_len = match record {
        Record::Start(s) => {
            u.settings.n_window.next = (s.n_window as u64).to_bits();
            u.settings.threshold.next = (s.threshold_int as u64).to_bits();
            u.settings.threshold_hold.next = (s.threshold_hold as u64).to_bits();
            u.settings.end_trim.next = (s.end_trim.unwrap() as u64).to_bits();
            u.settings.l_min.next = (s.l_min as u64).to_bits();
            u.settings.l_max.next = (s.l_max as u64).to_bits();
            u.settings.plane_period.next = (s.plane_period_ns as u64).to_bits();
            u.settings.masked_pixels.next = (s.masked_pixels as u64).to_bits();
            packet.len() - 4
        }
        Record::Blink(b) => {
            u.kind.next = 1.into();
            u.slot.next = (b.slot as u64).to_bits();
            // MASKED comes from the counter rows; the flag bit may come in
            // set as well (ORed).
            let masked = b.flags & flags::MASKED != 0;
            let keep = if masked && rng.gen() {
                flags::MASKED
            } else {
                0
            };
            u.flags.next = ((b.flags & !flags::MASKED | keep) as u64).to_bits();
            u.masked.next = masked;
            u.ax.next = (b.anchor_x as u64).to_bits();
            u.ay.next = (b.anchor_y as u64).to_bits();
            u.t0.next = b.t_cross.to_bits();
            u.t1.next = b.t_drop.to_bits();
            u.ts.next = (b.t_s as u64 & MAX_PLANE).to_bits();
            u.te.next = (b.t_e as u64 & MAX_PLANE).to_bits();
            u.planes.next = (b.planes_summed as u64).to_bits();
            // The head: the base's varint (bit 7 clear on its last byte), k.
            let varint = packet[45..].iter().position(|&x| x & 0x80 == 0).unwrap() + 1;
            let head = &packet[45..45 + varint + 1];
            for (i, h) in u.head.iter_mut().enumerate() {
                h.next = (head.get(i).copied().unwrap_or(0) as u64).to_bits();
            }
            45 + head.len()
        }
        Record::Dropped(d) => {
            u.kind.next = 2.into();
            u.t0.next = d.plane.to_bits();
            // The count's high 16 bits are not the packet's.
            u.t1.next = ((d.count as u64) | (rng.gen::<u16>() as u64) << 32).to_bits();
            u.ax.next = (d.first_x as u64).to_bits();
            u.ay.next = (d.first_y as u64).to_bits();
            packet.len() - 4
        }
        Record::End(e) => {
            u.kind.next = 3.into();
            u.c_planes.next = e.planes.to_bits();
            u.totals.blinks.next = e.blinks.to_bits();
            u.totals.unconfirmed.next = e.unconfirmed.to_bits();
            u.totals.dropped.next = e.dropped_candidates.to_bits();
            u.totals.bridged.next = e.bridged_dips.to_bits();
            u.totals.cuts.next = e.cut_segments.to_bits();
            packet.len() - 4
        }
        Record::Overflow(_) => unreachable!(),
    };
    packet[..prefix_len].to_vec()
}

fn lanes(v: &[Signal<Out, Bits<8>>]) -> Vec<u8> {
    v.iter().map(|s| s.val().to_u64() as u8).collect()
}

fn prefix_case(kernel: &[u32], r: usize, seed: u64) {
    let (cfg, bh) = config(kernel, r);
    let pb = bh.prefix_bytes();
    let mut u = RecordPrefix::<NW>::new(&bh);
    u.connect_all();
    check_all(&u).expect("rust-hdl design checks");
    let mut rng = common::rng(seed);
    for i in 0..400 {
        let kind = i % 4;
        let record = random_record(&mut rng, &cfg, kind);
        let seq: u32 = rng.gen();
        let mut packet = Vec::new();
        encode_record(&record, seq, &mut packet).unwrap();
        let expected = drive(&mut u, &mut rng, &record, seq, &packet);
        assert!(expected.len() <= pb, "{} bytes, {pb} lanes", expected.len());
        // The Overflow packet of the lost numbers driven.
        let (first, count) = (u.lost_first.next.to_u64(), u.lost_count.next.to_u64());
        let mut ovf = Vec::new();
        let o = OverflowRecord {
            first_seq: first as u32,
            count: (count as u32).max(1),
        };
        u.lost_count.next = (o.count as u64).to_bits();
        let first_seq = o.first_seq;
        encode_record(&Record::Overflow(o), first_seq, &mut ovf).unwrap();
        let enable = i % 9 != 8;
        u.enable.next = enable;
        settle(&mut u);
        let (rec, ov) = (lanes(&u.record), lanes(&u.overflow));
        if !enable {
            assert!(rec.iter().chain(&ov).all(|&x| x == 0), "lanes when off");
            continue;
        }
        assert_eq!(
            &rec[..expected.len()],
            &expected[..],
            "kind {kind}, record {i}"
        );
        assert!(
            rec[expected.len()..].iter().all(|&x| x == 0),
            "kind {kind}: past the prefix"
        );
        assert_eq!(&ov[..18], &ovf[..18], "Overflow prefix");
        assert!(ov[18..].iter().all(|&x| x == 0));
    }
}

#[test]
fn record_prefixes_are_the_models_packet_heads() {
    prefix_case(&[2, 10, 29, 54, 66, 54, 29, 10, 2], 9, 1);
    prefix_case(&[4, 24, 60, 80, 60, 24, 4], 7, 2);
}
