//! Tests of the packet format (`model/PACKETS.md`): round trips, corruption,
//! resynchronisation and loss accounting, frozen hex vectors, and the count
//! compression against the entropy of simulated blink ROIs.

use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Binomial, Distribution, Poisson};
use smartagg_model::packet::{
    decode_all, decode_frame, encode_record, newer_version_message, record_type, Decoder, Encoder,
    Event, FrameError, Packet, PacketError, PayloadError, SkipReason, BLINK_FIXED_LEN,
    DECODER_BUFFER, HEADER_LEN, MAX_PAYLOAD, VERSION,
};
use smartagg_model::record::{
    flags, BlinkRecord, DroppedRecord, OverflowRecord, Record, StreamEnd, StreamStart, MAX_PLANE,
};
use smartagg_model::rice;
use std::collections::HashMap;
use std::path::PathBuf;

const I48_MIN: i64 = -(1 << 47);
const I48_MAX: i64 = (1 << 47) - 1;

// ---------------------------------------------------------------- strategies

fn arb_start() -> impl Strategy<Value = StreamStart> {
    (
        (any::<u16>(), any::<u16>(), any::<u32>(), any::<u32>()),
        (any::<u32>(), any::<u32>(), any::<u8>(), any::<u8>()),
        (0u8..=15).prop_map(|h| 2 * h + 1),
        any::<u8>(),
        prop::collection::vec(any::<u16>(), 0..=255),
        (any::<u32>(), any::<u32>()),
    )
        .prop_map(
            |(
                (width, height, n_window, threshold_int),
                (l_min, l_max, r_assoc, slots),
                roi_size,
                kernel_shift,
                kernel,
                (plane_period_ns, masked_pixels),
            )| StreamStart {
                width,
                height,
                n_window,
                threshold_int,
                // Any value round-trips; the pipeline keeps it ≤ threshold_int.
                threshold_hold: threshold_int.rotate_left(7),
                end_trim: Some(n_window.rotate_left(13)),
                l_min,
                l_max,
                r_assoc,
                slots,
                roi_size,
                kernel_shift,
                kernel,
                plane_period_ns,
                masked_pixels,
            },
        )
}

/// Counts of an R×R ROI: small, huge, or mostly small with outliers.
fn arb_counts(r: u8) -> impl Strategy<Value = Vec<u32>> {
    let n = r as usize * r as usize;
    prop_oneof![
        prop::collection::vec(0u32..24, n),
        prop::collection::vec(any::<u32>(), n),
        prop::collection::vec(prop_oneof![9 => 0u32..60, 1 => any::<u32>()], n),
        (any::<u32>(), prop::collection::vec(0u32..8, n))
            .prop_map(|(b, v)| v.into_iter().map(|c| b.saturating_add(c)).collect()),
    ]
}

fn arb_blink() -> impl Strategy<Value = BlinkRecord> {
    (0u8..=15)
        .prop_map(|h| 2 * h + 1)
        .prop_flat_map(|roi_size| {
            (
                (any::<u8>(), any::<u8>(), any::<u16>(), any::<u16>()),
                (
                    0..=MAX_PLANE,
                    0..=MAX_PLANE,
                    I48_MIN..=I48_MAX,
                    I48_MIN..=I48_MAX,
                ),
                any::<u32>(),
                Just(roi_size),
                arb_counts(roi_size),
            )
        })
        .prop_map(
            |(
                (slot, flags, anchor_x, anchor_y),
                (t_cross, t_drop, t_s, t_e),
                planes_summed,
                roi_size,
                counts,
            )| BlinkRecord {
                slot,
                flags,
                anchor_x,
                anchor_y,
                t_cross,
                t_drop,
                t_s,
                t_e,
                planes_summed,
                roi_size,
                counts,
            },
        )
}

fn arb_dropped() -> impl Strategy<Value = DroppedRecord> {
    (0..=MAX_PLANE, any::<u32>(), any::<u16>(), any::<u16>()).prop_map(
        |(plane, count, first_x, first_y)| DroppedRecord {
            plane,
            count,
            first_x,
            first_y,
        },
    )
}

fn arb_end() -> impl Strategy<Value = StreamEnd> {
    any::<[u64; 6]>().prop_map(|v| StreamEnd {
        planes: v[0],
        blinks: v[1],
        unconfirmed: v[2],
        dropped_candidates: v[3],
        bridged_dips: v[4],
        cut_segments: v[5],
    })
}

/// Any record that takes a sequence number (everything but Overflow).
fn arb_seq_record() -> impl Strategy<Value = Record> {
    prop_oneof![
        1 => arb_start().prop_map(Record::Start),
        4 => arb_blink().prop_map(Record::Blink),
        1 => arb_dropped().prop_map(Record::Dropped),
        1 => arb_end().prop_map(Record::End),
    ]
}

fn arb_record() -> impl Strategy<Value = Record> {
    prop_oneof![
        4 => arb_seq_record(),
        1 => (any::<u32>(), 1u32..).prop_map(|(first_seq, count)| Record::Overflow(
            OverflowRecord { first_seq, count }
        )),
    ]
}

// ---------------------------------------------------------------- helpers

fn encode(record: &Record, seq: u32) -> Vec<u8> {
    let mut out = Vec::new();
    encode_record(record, seq, &mut out).expect("encodable record");
    out
}

/// Events from feeding `bytes` in chunks of the given sizes (cycled).
fn events_chunked(
    bytes: &[u8],
    chunks: &[usize],
) -> (Vec<Event>, smartagg_model::packet::LossStats) {
    let mut d = Decoder::new();
    let mut events = Vec::new();
    let mut rest = bytes;
    let mut i = 0;
    while !rest.is_empty() {
        let n = chunks[i % chunks.len()].clamp(1, rest.len());
        i += 1;
        d.feed(&rest[..n]);
        rest = &rest[n..];
        assert!(d.buffered() <= DECODER_BUFFER);
        while let Some(e) = d.next_event() {
            events.push(e);
        }
    }
    events.extend(d.finish());
    (events, d.stats().clone())
}

/// Every input byte is delivered, skipped or truncated: nothing vanishes.
fn assert_bytes_accounted(bytes_delivered: u64, s: &smartagg_model::packet::LossStats) {
    assert_eq!(
        s.bytes_in,
        bytes_delivered + s.bytes_skipped + s.truncated_tail_bytes,
        "byte accounting: {s:?}"
    );
}

fn packet_len(p: &Packet) -> u64 {
    encode(&p.record, p.seq).len() as u64
}

// ---------------------------------------------------------------- round trips

proptest! {
    // Integration tests have no lib.rs for proptest's regression files:
    // failures print their seed instead.
    #![proptest_config(ProptestConfig {
        cases: 400,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn every_record_round_trips(record in arb_record(), seq in any::<u32>()) {
        let seq = match &record { Record::Overflow(o) => o.first_seq, _ => seq };
        let bytes = encode(&record, seq);
        prop_assert!(bytes.len() <= HEADER_LEN + MAX_PAYLOAD + 4);
        let p = decode_frame(&bytes).expect("valid frame");
        prop_assert_eq!(p.seq, seq);
        prop_assert_eq!(&p.record, &record);
        // The stream decoder agrees and re-encoding gives the same bytes.
        let d = decode_all(&bytes);
        prop_assert_eq!(d.packets.len(), 1);
        prop_assert_eq!(&d.packets[0].record, &record);
        prop_assert_eq!(encode(&d.packets[0].record, seq), bytes);
        prop_assert_eq!(d.stats.packets_ok, 1);
        prop_assert_eq!(d.stats.crc_errors + d.stats.malformed + d.stats.bytes_skipped, 0);
    }

    #[test]
    fn stream_of_records_round_trips(records in prop::collection::vec(arb_seq_record(), 0..24)) {
        let mut enc = Encoder::new();
        let mut bytes = Vec::new();
        for r in &records {
            enc.push(r, &mut bytes).unwrap();
        }
        prop_assert_eq!(enc.next_seq() as usize, records.len());
        let d = decode_all(&bytes);
        let got: Vec<Record> = d.packets.iter().map(|p| p.record.clone()).collect();
        // A StreamStart at seq 0 only ever appears first here, so no resets.
        prop_assert_eq!(got, records.clone());
        for (i, p) in d.packets.iter().enumerate() {
            prop_assert_eq!(p.seq as usize, i);
        }
        prop_assert!(!d.stats.any_loss(), "{}", d.stats);
        prop_assert_eq!(d.stats.bytes_in, bytes.len() as u64);
    }

    /// Random bytes never panic the decoder and every byte is accounted for.
    #[test]
    fn random_garbage_never_panics(bytes in prop::collection::vec(any::<u8>(), 0..6000),
                                   chunks in prop::collection::vec(1usize..700, 1..8)) {
        let all = decode_all(&bytes);
        let delivered: u64 = all.packets.iter().map(packet_len).sum();
        assert_bytes_accounted(delivered, &all.stats);
        let (_, stats) = events_chunked(&bytes, &chunks);
        prop_assert_eq!(stats, all.stats);
    }

    /// Garbage made of spliced packet fragments (many plausible headers).
    #[test]
    fn spliced_fragments_never_panic(records in prop::collection::vec(arb_seq_record(), 1..8),
                                     cuts in prop::collection::vec((any::<prop::sample::Index>(), 0usize..200), 1..30)) {
        let mut enc = Encoder::new();
        let mut stream = Vec::new();
        for r in &records {
            enc.push(r, &mut stream).unwrap();
        }
        let mut bytes = Vec::new();
        for (at, len) in cuts {
            let a = at.index(stream.len());
            bytes.extend_from_slice(&stream[a..(a + len).min(stream.len())]);
        }
        let all = decode_all(&bytes);
        let delivered: u64 = all.packets.iter().map(packet_len).sum();
        assert_bytes_accounted(delivered, &all.stats);
        // Whatever is delivered is a record that was sent with that seq.
        for p in &all.packets {
            prop_assert_eq!(&p.record, &records[p.seq as usize]);
        }
    }

    /// Chunking never changes the events, even on corrupted streams.
    #[test]
    fn chunking_does_not_change_events(
        records in prop::collection::vec(arb_seq_record(), 1..12),
        flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..6),
        chunks in prop::collection::vec(1usize..300, 1..10),
        cut in any::<prop::sample::Index>(),
    ) {
        let mut enc = Encoder::new();
        let mut bytes = Vec::new();
        for r in &records {
            enc.push(r, &mut bytes).unwrap();
        }
        for (at, x) in flips {
            let i = at.index(bytes.len());
            bytes[i] ^= x;
        }
        // Sometimes cut the stream short, to exercise the truncated tail.
        let cut = if chunks[0] % 3 == 0 { cut.index(bytes.len() + 1) } else { bytes.len() };
        let bytes = &bytes[..cut];
        let (once, s1) = events_chunked(bytes, &[usize::MAX]);
        let (chunked, s2) = events_chunked(bytes, &chunks);
        let (bytewise, s3) = events_chunked(bytes, &[1]);
        prop_assert_eq!(&once, &chunked);
        prop_assert_eq!(&once, &bytewise);
        prop_assert_eq!(&s1, &s2);
        prop_assert_eq!(&s1, &s3);
        let delivered: u64 = once
            .iter()
            .map(|e| match e { Event::Packet(p) => packet_len(p), _ => 0 })
            .sum();
        assert_bytes_accounted(delivered, &s1);
    }
}

// ---------------------------------------------------------------- encoder errors

fn blink(roi_size: u8, counts: Vec<u32>) -> BlinkRecord {
    BlinkRecord {
        slot: 3,
        flags: 0,
        anchor_x: 100,
        anchor_y: 50,
        t_cross: 5000,
        t_drop: 5300,
        t_s: 4946,
        t_e: 5246,
        planes_summed: 409,
        roi_size,
        counts,
    }
}

#[test]
fn encoder_rejects_unrepresentable_records_and_writes_nothing() {
    let ok = blink(3, vec![1; 9]);
    let cases: Vec<(Record, u32, PacketError)> = vec![
        (
            Record::Blink(BlinkRecord {
                t_cross: MAX_PLANE + 1,
                ..ok.clone()
            }),
            0,
            PacketError::PlaneOutOfRange {
                field: "t_cross",
                value: MAX_PLANE + 1,
            },
        ),
        (
            Record::Blink(BlinkRecord {
                t_drop: u64::MAX,
                ..ok.clone()
            }),
            0,
            PacketError::PlaneOutOfRange {
                field: "t_drop",
                value: u64::MAX,
            },
        ),
        (
            Record::Blink(BlinkRecord {
                t_s: I48_MIN - 1,
                ..ok.clone()
            }),
            0,
            PacketError::SignedOutOfRange {
                field: "t_s",
                value: I48_MIN - 1,
            },
        ),
        (
            Record::Blink(BlinkRecord {
                t_e: I48_MAX + 1,
                ..ok.clone()
            }),
            0,
            PacketError::SignedOutOfRange {
                field: "t_e",
                value: I48_MAX + 1,
            },
        ),
        (
            Record::Blink(blink(4, vec![0; 16])),
            0,
            PacketError::BadRoiSize(4),
        ),
        (
            Record::Blink(blink(33, vec![0; 33 * 33])),
            0,
            PacketError::BadRoiSize(33),
        ),
        (
            Record::Blink(blink(3, vec![0; 8])),
            0,
            PacketError::CountsLength {
                roi_size: 3,
                expected: 9,
                got: 8,
            },
        ),
        (
            Record::Dropped(DroppedRecord {
                plane: 1 << 48,
                count: 1,
                first_x: 0,
                first_y: 0,
            }),
            0,
            PacketError::PlaneOutOfRange {
                field: "plane",
                value: 1 << 48,
            },
        ),
        (
            Record::Start(StreamStart {
                kernel: vec![1; 256],
                ..vector_start()
            }),
            0,
            PacketError::KernelTooLong(256),
        ),
        (
            Record::Start(StreamStart {
                roi_size: 0,
                ..vector_start()
            }),
            0,
            PacketError::BadRoiSize(0),
        ),
        (
            Record::Overflow(OverflowRecord {
                first_seq: 5,
                count: 0,
            }),
            5,
            PacketError::OverflowEmpty,
        ),
        (
            Record::Overflow(OverflowRecord {
                first_seq: 5,
                count: 2,
            }),
            6,
            PacketError::OverflowSeq {
                seq: 6,
                first_seq: 5,
            },
        ),
    ];
    for (record, seq, err) in cases {
        let mut out = vec![0xAA];
        assert_eq!(encode_record(&record, seq, &mut out), Err(err.clone()));
        assert_eq!(out, vec![0xAA], "nothing appended on error");
        assert!(!err.to_string().is_empty());
        let mut enc = Encoder::starting_at(seq);
        if !matches!(record, Record::Overflow(_)) {
            assert!(enc.push(&record, &mut out).is_err());
            assert_eq!(enc.next_seq(), seq, "a failed record takes no seq");
        }
    }
    // The extremes that do fit are accepted.
    let edge = BlinkRecord {
        t_cross: MAX_PLANE,
        t_drop: MAX_PLANE,
        t_s: I48_MIN,
        t_e: I48_MAX,
        ..ok
    };
    let bytes = encode(&Record::Blink(edge.clone()), 0);
    assert_eq!(decode_frame(&bytes).unwrap().record, Record::Blink(edge));
}

#[test]
fn worst_case_blink_fits_max_payload() {
    // Alternating 0 and 2^32-1 over 31x31 is the costliest ROI (33 bits each).
    let counts: Vec<u32> = (0..961)
        .map(|i| if i % 2 == 0 { 0 } else { u32::MAX })
        .collect();
    let b = Record::Blink(blink(31, counts));
    let bytes = encode(&b, 0);
    let payload = bytes.len() - HEADER_LEN - 4;
    assert!(payload <= BLINK_FIXED_LEN + rice::max_encoded_len(961));
    assert!(BLINK_FIXED_LEN + rice::max_encoded_len(961) <= MAX_PAYLOAD);
    assert_eq!(decode_frame(&bytes).unwrap().record, b);
}

// ---------------------------------------------------------------- corruption

/// A realistic stream: StreamStart, blinks with Poisson-like counts, dropped
/// records, StreamEnd.
fn sample_records(rng: &mut ChaCha8Rng, n: usize) -> Vec<Record> {
    let mut v = vec![Record::Start(vector_start())];
    for i in 0..n {
        if i % 9 == 4 {
            v.push(Record::Dropped(DroppedRecord {
                plane: rng.gen_range(0..1_000_000),
                count: rng.gen_range(1..4),
                first_x: rng.gen_range(0..320),
                first_y: rng.gen_range(0..240),
            }));
        } else {
            let lam: f64 = rng.gen_range(1.0..12.0);
            let pois = Poisson::new(lam).unwrap();
            let counts = (0..81).map(|_| pois.sample(rng) as u32).collect();
            let t_cross = rng.gen_range(0..1_000_000u64);
            v.push(Record::Blink(BlinkRecord {
                t_cross,
                t_drop: t_cross + rng.gen_range(100..1000),
                ..blink(9, counts)
            }));
        }
    }
    v.push(Record::End(StreamEnd {
        planes: 1_000_000,
        blinks: n as u64,
        ..StreamEnd::default()
    }));
    v
}

#[derive(Default, Debug)]
struct CorruptionTally {
    trials: u64,
    corruptions: u64,
    corrupted_packets: u64,
    noise_bursts: u64,
    crc_errors: u64,
    bytes_decoded: u64,
    /// Trials where a mutation rebuilt a frame or broke a neighbour.
    shifted_trials: u64,
}

/// Applies one random mutation to `p` that changes it (so its CRC must fail).
fn mutate(rng: &mut ChaCha8Rng, p: &mut Vec<u8>) {
    let op = if p.len() < 2 { 1 } else { rng.gen_range(0..5) };
    match op {
        0 => {
            let i = rng.gen_range(0..p.len());
            p[i] ^= 1 << rng.gen_range(0..8);
        }
        1 => {
            let i = rng.gen_range(0..p.len());
            p[i] ^= rng.gen_range(1..=255u8);
        }
        2 => {
            let i = rng.gen_range(0..p.len());
            p.remove(i);
        }
        3 => {
            // Inside the packet (not before its first or after its last byte).
            let i = rng.gen_range(1..p.len());
            p.insert(i, rng.gen());
        }
        _ => {
            let keep = rng.gen_range(0..p.len());
            p.truncate(keep);
        }
    }
}

/// The packets a correct decoder must deliver from a corrupted stream,
/// found without the decoder's logic: original frames that occur byte for
/// byte near where they were written (`starts`; a mutation can shift a
/// frame by a byte or two, e.g. deleting a packet's last byte when the next
/// packet starts with the same byte rebuilds it), taken left to right
/// without overlap. Noise and corrupted bytes form no CRC-valid frame except
/// with probability ~2^-32, which the test asserts never happens.
fn present_frames(
    stream: &[u8],
    packets: &[(u32, Record, Vec<u8>)],
    starts: &[usize],
) -> Vec<usize> {
    let mut found: Vec<(usize, usize)> = Vec::new();
    for (k, (_, _, frame)) in packets.iter().enumerate() {
        let lo = starts[k].saturating_sub(2);
        let hi = (starts[k] + 2).min(stream.len());
        for pos in lo..=hi {
            if stream.get(pos..pos + frame.len()) == Some(&frame[..]) {
                found.push((pos, k));
                break;
            }
        }
    }
    found.sort();
    let mut free_from = 0;
    let mut present = Vec::new();
    for (pos, k) in found {
        if pos >= free_from {
            present.push(k);
            free_from = pos + packets[k].2.len();
        }
    }
    present
}

/// Corrupts `packets` at random, decodes, and checks that exactly the packets
/// still present are delivered, unchanged, and that the losses add up.
fn corruption_trial(
    rng: &mut ChaCha8Rng,
    packets: &[(u32, Record, Vec<u8>)],
    pristine: &[u8],
    t: &mut CorruptionTally,
) {
    let mut bytes = Vec::new();
    let mut starts = Vec::with_capacity(packets.len());
    let mut corrupted = vec![false; packets.len()];
    let n_corrupt = rng.gen_range(1..=6);
    for _ in 0..n_corrupt {
        corrupted[rng.gen_range(0..packets.len())] = true;
    }
    for (i, (_, _, p)) in packets.iter().enumerate() {
        starts.push(bytes.len());
        if corrupted[i] {
            let mut p = p.clone();
            // Several mutations of the same packet are still one corrupted packet.
            for _ in 0..rng.gen_range(1..=2) {
                if !p.is_empty() {
                    mutate(rng, &mut p);
                    t.corruptions += 1;
                }
            }
            if p != packets[i].2 {
                t.corrupted_packets += 1;
            }
            bytes.extend_from_slice(&p);
        } else {
            bytes.extend_from_slice(p);
        }
        if rng.gen_ratio(1, 16) {
            let noise: Vec<u8> = (0..rng.gen_range(1..40)).map(|_| rng.gen()).collect();
            bytes.extend_from_slice(&noise);
            t.noise_bursts += 1;
        }
    }
    let d = decode_all(&bytes);
    t.trials += 1;
    t.bytes_decoded += bytes.len() as u64;
    t.crc_errors += d.stats.crc_errors;

    let present = present_frames(&bytes, packets, &starts);
    let labelled: Vec<usize> = (0..packets.len()).filter(|&i| !corrupted[i]).collect();
    if present != labelled {
        t.shifted_trials += 1;
    }
    let delivered: Vec<u32> = d.packets.iter().map(|p| p.seq).collect();
    let expected: Vec<u32> = present.iter().map(|&k| packets[k].0).collect();
    assert_eq!(delivered, expected, "stats {:?}", d.stats);
    for (p, &k) in d.packets.iter().zip(&present) {
        assert_eq!(p.record, packets[k].1, "delivered with wrong contents");
    }
    // Every missing packet before the last delivered one is counted lost;
    // those after it cannot be (nothing follows them).
    let last = present.last().map_or(0, |&k| k + 1);
    assert_eq!(d.stats.lost_in_transport, (last - present.len()) as u64);
    assert_eq!(d.stats.lost_on_device, 0);
    if present.last() == Some(&(packets.len() - 1)) {
        assert_eq!(
            d.stats.packets_ok + d.stats.lost_in_transport,
            packets.len() as u64
        );
    }
    // Two mutations of one packet may cancel out (flip and flip back), and a
    // last packet truncated to nothing leaves no trace.
    let at_boundary = bytes.is_empty()
        || packets
            .iter()
            .scan(0, |end, (_, _, p)| {
                *end += p.len();
                Some(*end)
            })
            .any(|end| end == bytes.len());
    let clean_prefix = at_boundary && pristine.starts_with(&bytes);
    assert_eq!(d.stats.any_loss(), !clean_prefix);
    let delivered_bytes: u64 = present.iter().map(|&k| packets[k].2.len() as u64).sum();
    assert_bytes_accounted(delivered_bytes, &d.stats);
}

#[test]
fn corrupted_streams_are_detected_and_losses_exact() {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5A5A);
    let records = sample_records(&mut rng, 20);
    let mut enc = Encoder::new();
    let packets: Vec<(u32, Record, Vec<u8>)> = records
        .iter()
        .map(|r| {
            let seq = enc.next_seq();
            let mut b = Vec::new();
            enc.push(r, &mut b).unwrap();
            (seq, r.clone(), b)
        })
        .collect();
    let pristine: Vec<u8> = packets.iter().flat_map(|p| p.2.iter().copied()).collect();
    let mut t = CorruptionTally::default();
    let clock = std::time::Instant::now();
    while t.corruptions < 200_000 {
        corruption_trial(&mut rng, &packets, &pristine, &mut t);
    }
    // Printed for information only (timings are never asserted).
    let secs = clock.elapsed().as_secs_f64();
    println!(
        "corruption test: {t:?} in {secs:.2} s ({:.0} MB/s of corrupted stream generated, decoded and checked)",
        t.bytes_decoded as f64 / secs / 1e6
    );
    assert!(t.corruptions >= 200_000);
    assert!(t.crc_errors > 0);
}

#[test]
fn truncated_streams_count_the_tail() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let records = sample_records(&mut rng, 5);
    let mut enc = Encoder::new();
    let mut bytes = Vec::new();
    let mut ends = Vec::new();
    for r in &records {
        enc.push(r, &mut bytes).unwrap();
        ends.push(bytes.len());
    }
    for cut in 0..=bytes.len() {
        let complete = ends.iter().filter(|&&e| e <= cut).count();
        let last_end = if complete == 0 { 0 } else { ends[complete - 1] };
        let d = decode_all(&bytes[..cut]);
        assert_eq!(d.packets.len(), complete, "cut at {cut}");
        assert_eq!(d.stats.truncated_tail_bytes, (cut - last_end) as u64);
        assert_eq!(d.stats.bytes_skipped, 0);
        assert_eq!(d.stats.lost_in_transport, 0);
        assert_eq!(d.stats.any_loss(), cut != last_end);
    }
}

#[test]
fn zero_length_stream() {
    let d = decode_all(&[]);
    assert!(d.packets.is_empty());
    assert_eq!(d.stats, Default::default());
    assert!(!d.stats.any_loss());
    assert!(d.stats.to_string().contains("nothing lost"));
    let mut dec = Decoder::new();
    dec.feed(&[]);
    assert!(dec.next_event().is_none());
    assert!(dec.finish().is_empty());
}

#[test]
fn corrupted_length_hiding_the_last_packets_is_resolved_at_finish() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let records = sample_records(&mut rng, 3);
    let packets: Vec<Vec<u8>> = records
        .iter()
        .enumerate()
        .map(|(i, r)| encode(r, i as u32))
        .collect();
    let mut bytes = Vec::new();
    for (i, p) in packets.iter().enumerate() {
        let mut p = p.clone();
        if i == 1 {
            // Claims a payload longer than the rest of the stream.
            p[8..10].copy_from_slice(&4000u16.to_le_bytes());
        }
        bytes.extend_from_slice(&p);
    }
    let d = decode_all(&bytes);
    let seqs: Vec<u32> = d.packets.iter().map(|p| p.seq).collect();
    let expect: Vec<u32> = (0..records.len() as u32).filter(|&s| s != 1).collect();
    assert_eq!(seqs, expect);
    assert_eq!(d.stats.lost_in_transport, 1);
    assert_eq!(d.stats.truncated_tail_bytes, 0);
    assert_eq!(d.stats.bytes_skipped, packets[1].len() as u64);
    assert_eq!(d.stats.crc_errors, 0, "its CRC was never checkable");
}

#[test]
fn shuffled_packets_are_reported_as_gaps() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let records = sample_records(&mut rng, 4);
    let p: Vec<Vec<u8>> = records
        .iter()
        .enumerate()
        .map(|(i, r)| encode(r, i as u32))
        .collect();
    // Order 0 2 1 3 4 5: documented as a forward gap, a backward jump, and a
    // gap again (transport loss over-counted, never under-counted).
    let order = [0usize, 2, 1, 3, 4, 5];
    let bytes: Vec<u8> = order.iter().flat_map(|&i| p[i].clone()).collect();
    let mut d = Decoder::new();
    d.feed(&bytes);
    let events = d.finish();
    let gaps: Vec<(u32, u32, u32, bool)> = events
        .iter()
        .filter_map(|e| match e {
            Event::Gap {
                expected,
                got,
                lost,
                on_device,
            } => Some((*expected, *got, *lost, *on_device)),
            _ => None,
        })
        .collect();
    assert_eq!(
        gaps,
        vec![(1, 2, 1, false), (3, 1, 0, false), (2, 3, 1, false)]
    );
    let s = d.stats();
    assert_eq!(s.packets_ok, 6);
    assert_eq!(s.out_of_order, 1);
    assert_eq!(s.lost_in_transport, 2);
    assert!(s.to_string().contains("out of order"));
}

#[test]
fn duplicated_streams_and_packets() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let records = sample_records(&mut rng, 6);
    let mut enc = Encoder::new();
    let mut one = Vec::new();
    for r in &records {
        enc.push(r, &mut one).unwrap();
    }
    // The whole stream twice (two captures in one file): a new StreamStart at
    // seq 0 restarts the sequence, nothing is lost.
    let twice = [one.clone(), one.clone()].concat();
    let d = decode_all(&twice);
    assert_eq!(d.packets.len(), 2 * records.len());
    assert!(!d.stats.any_loss(), "{}", d.stats);
    assert_eq!(d.stats.out_of_order, 0);
    // One packet repeated in place: a backward jump, nothing lost.
    let p2 = encode(&records[2], 2);
    let mut bytes = Vec::new();
    for (i, r) in records.iter().enumerate() {
        bytes.extend(encode(r, i as u32));
        if i == 2 {
            bytes.extend_from_slice(&p2);
        }
    }
    let d = decode_all(&bytes);
    assert_eq!(d.packets.len(), records.len() + 1);
    assert_eq!(d.stats.out_of_order, 1);
    assert_eq!(d.stats.lost_in_transport, 0);
    assert!(!d.stats.any_loss());
}

#[test]
fn stream_joined_midway_counts_the_missed_start() {
    // The host attached after 10 records: the decoder expects seq 0 first.
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let records = sample_records(&mut rng, 3);
    let mut enc = Encoder::starting_at(10);
    let mut bytes = Vec::new();
    for r in &records[1..] {
        enc.push(r, &mut bytes).unwrap();
    }
    let d = decode_all(&bytes);
    assert_eq!(d.stats.lost_in_transport, 10);
    assert_eq!(d.packets.len(), records.len() - 1);
}

#[test]
fn sequence_numbers_wrap() {
    let b = Record::Blink(blink(1, vec![7]));
    let mut bytes = encode(&Record::Start(vector_start()), 0);
    for seq in [0x7FFF_FFFF, u32::MAX - 1, u32::MAX, 0, 1] {
        bytes.extend(encode(&b, seq));
    }
    let d = decode_all(&bytes);
    assert_eq!(d.packets.len(), 6);
    // 1..0x7FFF_FFFF and 0x8000_0000..u32::MAX-1 are missing; the wrap is not a gap.
    assert_eq!(d.stats.lost_in_transport, 2 * (0x7FFF_FFFE_u64));
    assert_eq!(d.stats.out_of_order, 0);
}

// ---------------------------------------------------------------- overflow

#[test]
fn overflow_records_account_device_losses_exactly() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let records = sample_records(&mut rng, 200);
    let mut enc = Encoder::new();
    let mut bytes = Vec::new();
    let mut dropped_total = 0u64;
    let mut overflows = 0u64;
    let mut i = 0;
    let mut kept = 0u64;
    // The gateware's FIFO: records are numbered, then some are dropped and an
    // Overflow record takes their place before the next surviving record.
    while i < records.len() {
        if i > 0 && i + 5 < records.len() && rng.gen_ratio(1, 10) {
            let n = rng.gen_range(1..5);
            let first_seq = enc.next_seq();
            for r in &records[i..i + n] {
                enc.push(r, &mut Vec::new()).unwrap();
            }
            enc.push(
                &Record::Overflow(OverflowRecord {
                    first_seq,
                    count: n as u32,
                }),
                &mut bytes,
            )
            .unwrap();
            assert_eq!(
                enc.next_seq(),
                first_seq + n as u32,
                "overflow takes no seq"
            );
            dropped_total += n as u64;
            overflows += 1;
            i += n;
        } else {
            enc.push(&records[i], &mut bytes).unwrap();
            kept += 1;
            i += 1;
        }
    }
    assert!(overflows > 5);
    let mut d = Decoder::new();
    d.feed(&bytes);
    let events = d.finish();
    let s = d.stats();
    assert_eq!(s.lost_on_device, dropped_total);
    assert_eq!(s.lost_in_transport, 0);
    assert_eq!(s.packets_ok, kept + overflows);
    assert_eq!(
        s.packets_ok - overflows + s.lost_on_device,
        records.len() as u64
    );
    let device_gaps: u64 = events
        .iter()
        .map(|e| match e {
            Event::Gap {
                lost,
                on_device: true,
                ..
            } => *lost as u64,
            Event::Gap {
                on_device: false, ..
            } => panic!("no transport gap expected"),
            _ => 0,
        })
        .sum();
    assert_eq!(device_gaps, dropped_total);
    assert!(s.any_loss());
    assert!(s.to_string().contains("lost on the device"));

    // Now also lose the packet after an Overflow in transport: the two kinds
    // are told apart.
    let mut d2 = Decoder::new();
    let mut b2 = encode(&Record::Start(vector_start()), 0);
    b2.extend(encode(
        &Record::Overflow(OverflowRecord {
            first_seq: 3,
            count: 2,
        }),
        3,
    ));
    b2.extend(encode(&Record::Blink(blink(1, vec![1])), 6));
    d2.feed(&b2);
    let ev = d2.finish();
    let gaps: Vec<_> = ev
        .iter()
        .filter_map(|e| match e {
            Event::Gap {
                expected,
                got,
                lost,
                on_device,
            } => Some((*expected, *got, *lost, *on_device)),
            _ => None,
        })
        .collect();
    assert_eq!(
        gaps,
        vec![(1, 3, 2, false), (3, 5, 2, true), (5, 6, 1, false)]
    );
    assert_eq!(d2.stats().lost_in_transport, 3);
    assert_eq!(d2.stats().lost_on_device, 2);
}

// ---------------------------------------------------------------- versions, malformed, memory

/// A frame with an arbitrary header, payload and a correct CRC.
fn raw_frame(version: u8, kind: u8, seq: u32, payload: &[u8]) -> Vec<u8> {
    let mut f = vec![0x53, 0x41, version, kind];
    f.extend_from_slice(&seq.to_le_bytes());
    f.extend_from_slice(&(payload.len() as u16).to_le_bytes());
    f.extend_from_slice(payload);
    let crc = smartagg_model::packet::crc32c(&f);
    f.extend_from_slice(&crc.to_le_bytes());
    f
}

#[test]
fn newer_version_is_visible() {
    let mut bytes = encode(&Record::Start(vector_start()), 0);
    let v2 = raw_frame(4, 0x02, 1, &[1, 2, 3, 4, 5]);
    bytes.extend_from_slice(&v2);
    // A bogus "version 9" header with a bad CRC is noise, not a newer version.
    let mut bogus = raw_frame(9, 0x01, 1, &[0; 8]);
    let n = bogus.len();
    bogus[n - 1] ^= 0xFF;
    bytes.extend_from_slice(&bogus);
    bytes.extend(encode(&Record::End(StreamEnd::default()), 1));
    let mut d = Decoder::new();
    d.feed(&bytes);
    let events = d.finish();
    assert!(events.contains(&Event::Skipped {
        bytes: v2.len() as u64,
        reason: SkipReason::NewerVersion(4)
    }));
    assert_eq!(d.stats().newer_version, 1);
    assert_eq!(d.stats().crc_errors, 1);
    assert_eq!(d.newer_version_seen(), Some(4));
    assert_eq!(
        newer_version_message(4),
        "stream format version 4 is newer than this smartagg supports (3)"
    );
    assert_eq!(VERSION, 3);
    assert!(d.stats().any_loss());
    assert!(d.stats().to_string().contains("newer"));
    assert_eq!(decode_frame(&v2), Err(FrameError::NewerVersion(4)));
}

#[test]
fn malformed_payloads_are_counted_not_delivered() {
    let good = raw_frame(1, record_type::OVERFLOW, 4, &[4, 0, 0, 0, 1, 0, 0, 0]);
    assert!(decode_frame(&good).is_ok());
    let cases: Vec<(Vec<u8>, PayloadError)> = vec![
        (raw_frame(1, 0x05, 1, &[]), PayloadError::UnknownType(0x05)),
        (
            raw_frame(1, record_type::DROPPED, 1, &[0; 13]),
            PayloadError::Length {
                record: "dropped",
                expected: 14,
                got: 13,
            },
        ),
        (
            raw_frame(1, record_type::STREAM_END, 1, &[0; 49]),
            PayloadError::Length {
                record: "stream-end",
                expected: 48,
                got: 49,
            },
        ),
        (
            raw_frame(1, record_type::BLINK, 1, &[0; 34]),
            PayloadError::TooShort {
                record: "blink",
                min: 35,
                got: 34,
            },
        ),
        (
            raw_frame(1, record_type::OVERFLOW, 4, &[4, 0, 0, 0, 0, 0, 0, 0]),
            PayloadError::OverflowEmpty,
        ),
        (
            raw_frame(1, record_type::OVERFLOW, 5, &[4, 0, 0, 0, 1, 0, 0, 0]),
            PayloadError::OverflowSeq {
                seq: 5,
                first_seq: 4,
            },
        ),
        (
            {
                let mut p = vec![0u8; 35];
                p[34] = 2;
                raw_frame(1, record_type::BLINK, 1, &p)
            },
            PayloadError::BadRoiSize(2),
        ),
        (
            {
                // R = 1, count block: base 0, k = 0, code "0" then a stray byte.
                let mut p = vec![0u8; 35];
                p[34] = 1;
                p.extend_from_slice(&[0, 0, 0, 0]);
                raw_frame(1, record_type::BLINK, 1, &p)
            },
            PayloadError::Counts(rice::RiceError::TrailingBytes(1)),
        ),
        (
            {
                let mut p = vec![0u8; 35];
                p[34] = 1;
                p.extend_from_slice(&[0, 40, 0]);
                raw_frame(1, record_type::BLINK, 1, &p)
            },
            PayloadError::Counts(rice::RiceError::BadK(40)),
        ),
        (
            {
                // Kernel length byte says 3 weights but none follow.
                let mut p = encode(
                    &Record::Start(StreamStart {
                        kernel: vec![],
                        ..vector_start()
                    }),
                    0,
                )[HEADER_LEN..]
                    .to_vec();
                p.truncate(p.len() - 4);
                p[24] = 3;
                raw_frame(VERSION, record_type::STREAM_START, 0, &p)
            },
            PayloadError::Length {
                record: "stream-start",
                expected: 47,
                got: 41,
            },
        ),
    ];
    for (frame, err) in cases {
        assert_eq!(
            decode_frame(&frame),
            Err(FrameError::Malformed(err.clone()))
        );
        let mut d = Decoder::new();
        d.feed(&frame);
        let events = d.finish();
        assert_eq!(
            events,
            vec![Event::Skipped {
                bytes: frame.len() as u64,
                reason: SkipReason::Malformed(err)
            }]
        );
        assert_eq!(d.stats().malformed, 1);
        assert_eq!(d.stats().packets_ok, 0);
        assert_eq!(d.stats().bytes_skipped, frame.len() as u64);
    }
}

#[test]
fn decoder_memory_is_bounded() {
    // A plausible header claiming the maximum payload, then a long valid
    // stream fed in one call and in odd chunks: the buffer never exceeds the
    // bound, and the stream behind the bogus header is decoded.
    let mut bytes = vec![0x53, 0x41, 1, 2, 0, 0, 0, 0];
    bytes.extend_from_slice(&(MAX_PAYLOAD as u16).to_le_bytes());
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let records = sample_records(&mut rng, 3000);
    let mut enc = Encoder::new();
    for r in &records {
        enc.push(r, &mut bytes).unwrap();
    }
    assert!(bytes.len() > 20 * DECODER_BUFFER);
    let mut d = Decoder::new();
    d.feed(&bytes);
    assert!(d.buffered() <= DECODER_BUFFER);
    let mut n = 0;
    while let Some(e) = d.next_event() {
        n += matches!(e, Event::Packet(_)) as usize;
    }
    n += d
        .finish()
        .iter()
        .filter(|e| matches!(e, Event::Packet(_)))
        .count();
    assert_eq!(n, records.len());
    assert_eq!(d.stats().crc_errors, 1);
    let (_, stats) = events_chunked(&bytes, &[1, 4097, 13, 8191, 3]);
    assert_eq!(&stats, d.stats());
}

#[test]
fn crc_is_crc32c() {
    // The standard CRC-32C check value.
    assert_eq!(smartagg_model::packet::crc32c(b"123456789"), 0xE306_9283);
}

// ---------------------------------------------------------------- hex vectors

fn vector_start() -> StreamStart {
    StreamStart {
        width: 320,
        height: 240,
        n_window: 108,
        threshold_int: 1_234_567,
        threshold_hold: 654_321,
        end_trim: Some(54),
        l_min: 3,
        l_max: 10_000,
        r_assoc: 1,
        slots: 32,
        roi_size: 9,
        kernel_shift: 8,
        kernel: vec![4, 24, 60, 80, 60, 24, 4],
        plane_period_ns: 100_000,
        masked_pixels: 5,
    }
}

#[rustfmt::skip]
const VECTOR_BLINK_COUNTS: [u32; 81] = [
    2, 3, 1, 4, 2, 3, 2, 1, 3,
    3, 2, 4, 5, 6, 4, 3, 2, 2,
    1, 4, 7, 11, 13, 10, 6, 3, 2,
    3, 5, 12, 21, 27, 20, 11, 4, 3,
    2, 6, 14, 26, 34, 25, 13, 5, 1,
    4, 5, 11, 19, 24, 18, 10, 4, 2,
    2, 3, 6, 9, 12, 8, 5, 3, 3,
    1, 2, 3, 4, 5, 3, 4, 2, 1,
    3, 1, 2, 3, 2, 2, 1, 3, 2,
];

fn vector_blink() -> BlinkRecord {
    BlinkRecord {
        slot: 5,
        flags: 0,
        anchor_x: 161,
        anchor_y: 97,
        t_cross: 123_456,
        t_drop: 123_789,
        t_s: 123_402,
        t_e: 123_735,
        // [t_cross − N, t_drop − end_trim] (version 3; 442 to t_drop in 1 and 2).
        planes_summed: 388,
        roi_size: 9,
        counts: VECTOR_BLINK_COUNTS.to_vec(),
    }
}

/// Anchor (2, 1) on a 320x240 sensor: the two left columns and three top
/// rows of the 9x9 ROI are outside (zero); near stream start so t_s < 0.
fn vector_blink_edge() -> BlinkRecord {
    let mut counts = vec![0u32; 81];
    for y in 3..9 {
        for x in 2..9 {
            let r2 = (x as i32 - 4).pow(2) + (y as i32 - 4).pow(2);
            counts[y * 9 + x] = 2 + (20 >> r2.min(5)) as u32 + ((x * 7 + y * 3) % 3) as u32;
        }
    }
    BlinkRecord {
        slot: 0,
        flags: flags::EDGE | flags::PREROLL_CLIPPED,
        anchor_x: 2,
        anchor_y: 1,
        t_cross: 40,
        t_drop: 260,
        t_s: -14,
        t_e: 206,
        // [0, t_drop − end_trim] (version 3; 261 to t_drop in 1 and 2).
        planes_summed: 207,
        roi_size: 9,
        counts,
    }
}

/// Huge counts (a 5-byte base varint and an escaped code) and the largest
/// plane indices.
fn vector_blink_large() -> BlinkRecord {
    let mut counts = vec![1_000_000_000u32; 9];
    counts[4] = u32::MAX;
    counts[0] = 1_000_000_003;
    BlinkRecord {
        slot: 31,
        flags: flags::CUT | flags::CONTINUATION,
        anchor_x: 319,
        anchor_y: 239,
        t_cross: MAX_PLANE - 1000,
        t_drop: MAX_PLANE,
        // Extremes of the field widths rather than a consistent blink.
        t_s: I48_MAX - 1000,
        t_e: I48_MAX,
        planes_summed: u32::MAX,
        roi_size: 3,
        counts,
    }
}

fn vector_dropped() -> DroppedRecord {
    DroppedRecord {
        plane: 0x0000_1234_5678_9ABC,
        count: 3,
        first_x: 300,
        first_y: 17,
    }
}

fn vector_end() -> StreamEnd {
    StreamEnd {
        planes: 600_000,
        blinks: 1_234,
        unconfirmed: 56_789,
        dropped_candidates: 12,
        bridged_dips: 345,
        cut_segments: 6,
    }
}

/// The frozen vectors: file name and the (seq, record) packets it holds.
fn vectors() -> Vec<(&'static str, Vec<(u32, Record)>)> {
    vectors_described()
        .into_iter()
        .map(|(f, _, p)| (f, p))
        .collect()
}

/// A vector file: name, one-line description, and its (seq, record) packets.
type Vector = (&'static str, &'static str, Vec<(u32, Record)>);

/// [`vectors`] with the one-line description at the top of each file.
fn vectors_described() -> Vec<Vector> {
    let overflow = Record::Overflow(OverflowRecord {
        first_seq: 42,
        count: 7,
    });
    vec![
        ("stream_start.hex", "StreamStart of a SPCImager-like configuration, seq 0", vec![(0, Record::Start(vector_start()))]),
        ("blink.hex", "Blink, 9x9 ROI with a PSF bump, seq 1", vec![(1, Record::Blink(vector_blink()))]),
        ("blink_edge.hex", "Blink at the sensor corner (EDGE flag, outside pixels 0), negative t_s, seq 2", vec![(2, Record::Blink(vector_blink_edge()))]),
        ("blink_large.hex", "Blink, 3x3 ROI with huge counts (5-byte base varint, escape code), largest plane fields, seq 3", vec![(3, Record::Blink(vector_blink_large()))]),
        ("dropped.hex", "Dropped, seq 4", vec![(4, Record::Dropped(vector_dropped()))]),
        ("stream_end.hex", "StreamEnd, seq 5", vec![(5, Record::End(vector_end()))]),
        ("overflow.hex", "Overflow of the 7 records 42-48: header seq = first_seq = 42", vec![(42, overflow)]),
        (
            "stream.hex",
            "a short stream: StreamStart, Blink, Dropped, Overflow of seqs 3-4, Blink, StreamEnd",
            vec![
                (0, Record::Start(vector_start())),
                (1, Record::Blink(vector_blink())),
                (2, Record::Dropped(vector_dropped())),
                (
                    3,
                    Record::Overflow(OverflowRecord {
                        first_seq: 3,
                        count: 2,
                    }),
                ),
                (5, Record::Blink(vector_blink_edge())),
                (6, Record::End(vector_end())),
            ],
        ),
    ]
}

fn vector_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/vectors")
}

/// Parses the hex-vector text format: `#` starts a comment to end of line,
/// whitespace is ignored, the rest is pairs of hex digits.
fn parse_hex(text: &str) -> Vec<u8> {
    let digits: String = text
        .lines()
        .map(|l| l.split('#').next().unwrap_or(""))
        .flat_map(|l| l.chars().filter(|c| !c.is_whitespace()))
        .collect();
    hex::decode(&digits).expect("hex digits in pairs")
}

/// Annotated hex of a frame (the format of the checked-in files).
fn annotate(frame: &[u8]) -> String {
    struct Lines<'a> {
        frame: &'a [u8],
        at: usize,
        text: String,
    }
    impl Lines<'_> {
        fn put(&mut self, n: usize, what: String) {
            let h: Vec<String> = self.frame[self.at..self.at + n]
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect();
            self.text
                .push_str(&format!("{:<36}# {}\n", h.join(" "), what));
            self.at += n;
        }
    }
    let mut s = Lines {
        frame,
        at: 0,
        text: String::new(),
    };
    let p = decode_frame(frame).expect("valid frame");
    let len = u16::from_le_bytes([frame[8], frame[9]]) as usize;
    s.put(2, "magic \"SA\"".into());
    s.put(1, format!("version {}", frame[2]));
    let name = match frame[3] {
        record_type::STREAM_START => "StreamStart",
        record_type::BLINK => "Blink",
        record_type::DROPPED => "Dropped",
        record_type::STREAM_END => "StreamEnd",
        _ => "Overflow",
    };
    s.put(1, format!("record type 0x{:02x} {name}", frame[3]));
    s.put(4, format!("seq {}", p.seq));
    s.put(2, format!("payload length {len}"));
    match &p.record {
        Record::Start(r) => {
            s.put(2, format!("width {}", r.width));
            s.put(2, format!("height {}", r.height));
            s.put(4, format!("n_window {}", r.n_window));
            s.put(4, format!("threshold_int {}", r.threshold_int));
            s.put(4, format!("l_min {}", r.l_min));
            s.put(4, format!("l_max {}", r.l_max));
            s.put(1, format!("r_assoc {}", r.r_assoc));
            s.put(1, format!("slots {}", r.slots));
            s.put(1, format!("roi_size {}", r.roi_size));
            s.put(1, format!("kernel_shift {}", r.kernel_shift));
            s.put(1, format!("kernel length {}", r.kernel.len()));
            for w in &r.kernel {
                s.put(2, format!("kernel weight {w}"));
            }
            s.put(4, format!("plane_period_ns {}", r.plane_period_ns));
            s.put(4, format!("masked_pixels {}", r.masked_pixels));
            if frame[2] >= 2 {
                s.put(4, format!("threshold_hold {}", r.threshold_hold));
            }
            if let Some(c) = r.end_trim {
                s.put(4, format!("end_trim {c}"));
            }
        }
        Record::Blink(b) => {
            s.put(1, format!("slot {}", b.slot));
            s.put(1, format!("flags 0x{:02x}", b.flags));
            s.put(2, format!("anchor_x {}", b.anchor_x));
            s.put(2, format!("anchor_y {}", b.anchor_y));
            s.put(6, format!("t_cross {}", b.t_cross));
            s.put(6, format!("t_drop {}", b.t_drop));
            s.put(6, format!("t_s {}", b.t_s));
            s.put(6, format!("t_e {}", b.t_e));
            s.put(4, format!("planes_summed {}", b.planes_summed));
            s.put(1, format!("roi_size {}", b.roi_size));
            let r = b.roi_size as usize;
            for (y, row) in b.counts.chunks(r).enumerate() {
                let row: Vec<String> = row.iter().map(|c| c.to_string()).collect();
                s.text
                    .push_str(&format!("# counts row {y}: {}\n", row.join(" ")));
            }
            let (base, k, bits) = rice::choose(&b.counts);
            s.put(
                rice::varint_len(base),
                format!("count base {base} (LEB128)"),
            );
            s.put(1, format!("Rice k {k}"));
            let code_bytes = bits.div_ceil(8) as usize;
            let mut left = code_bytes;
            let mut first = true;
            while left > 0 {
                let n = left.min(12);
                let what = if first {
                    format!(
                        "Rice codes, {bits} bits + {} padding",
                        code_bytes * 8 - bits as usize
                    )
                } else {
                    "...".to_string()
                };
                s.put(n, what);
                first = false;
                left -= n;
            }
        }
        Record::Dropped(d) => {
            s.put(6, format!("plane {}", d.plane));
            s.put(4, format!("count {}", d.count));
            s.put(2, format!("first_x {}", d.first_x));
            s.put(2, format!("first_y {}", d.first_y));
        }
        Record::End(e) => {
            for (name, v) in [
                ("planes", e.planes),
                ("blinks", e.blinks),
                ("unconfirmed", e.unconfirmed),
                ("dropped_candidates", e.dropped_candidates),
                ("bridged_dips", e.bridged_dips),
                ("cut_segments", e.cut_segments),
            ] {
                s.put(8, format!("{name} {v}"));
            }
        }
        Record::Overflow(o) => {
            s.put(4, format!("first_seq {}", o.first_seq));
            s.put(4, format!("count {}", o.count));
        }
    }
    let crc = u32::from_le_bytes(frame[s.at..s.at + 4].try_into().unwrap());
    s.put(4, format!("CRC-32C 0x{crc:08x}"));
    assert_eq!(s.at, frame.len());
    s.text
}

/// The annotated text of a vector file (used to create the frozen files once,
/// and shown when a frozen file no longer matches the encoder).
fn vector_text(file: &str, description: &str, packets: &[(u32, Record)]) -> String {
    let mut text = format!(
        "# {file}: {description}\n# smartagg packet format version 3, see model/PACKETS.md. \
         FROZEN: never regenerate.\n\n"
    );
    let frames: Vec<String> = packets
        .iter()
        .map(|(seq, r)| annotate(&encode(r, *seq)))
        .collect();
    text.push_str(&frames.join("\n"));
    text
}

#[test]
fn hex_vectors_are_frozen() {
    for (file, description, packets) in vectors_described() {
        let expected: Vec<u8> = packets
            .iter()
            .flat_map(|(seq, r)| encode(r, *seq))
            .collect();
        let regenerated = vector_text(file, description, &packets);
        let path = vector_dir().join(file);
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| {
            panic!("{}: {e}\nthe encoder gives:\n{regenerated}", path.display())
        });
        let bytes = parse_hex(&text);
        assert_eq!(
            bytes, expected,
            "{file}: the frozen bytes differ from the encoder's; the encoder gives:\n{regenerated}"
        );
        let d = decode_all(&bytes);
        let got: Vec<(u32, Record)> = d.packets.into_iter().map(|p| (p.seq, p.record)).collect();
        assert_eq!(got, packets, "{file}");
        // The decoder expects seq 0 first: a lone vector with seq s shows a
        // transport gap of s.
        assert_eq!(d.stats.lost_in_transport, packets[0].0 as u64, "{file}");
        assert_eq!(
            d.stats.bytes_skipped + d.stats.crc_errors + d.stats.truncated_tail_bytes,
            0
        );
        let device = match file {
            "stream.hex" => 2,
            "overflow.hex" => 7,
            _ => 0,
        };
        assert_eq!(d.stats.lost_on_device, device, "{file}");
        for (seq, r) in &packets {
            assert_eq!(decode_frame(&encode(r, *seq)).unwrap().record, *r);
        }
    }
}

/// The records of the vectors as a stream of format `version` (1 or 2)
/// carries them: no end_trim, (version 1) one threshold, and the Blinks of
/// the vectors summed to t_drop.
fn as_older_version(r: &Record, version: u8) -> Record {
    match r {
        Record::Start(s) => Record::Start(StreamStart {
            threshold_hold: if version == 1 {
                s.threshold_int
            } else {
                s.threshold_hold
            },
            end_trim: None,
            ..s.clone()
        }),
        Record::Blink(b) if *b == vector_blink() => Record::Blink(BlinkRecord {
            planes_summed: 442,
            ..b.clone()
        }),
        Record::Blink(b) if *b == vector_blink_edge() => Record::Blink(BlinkRecord {
            planes_summed: 261,
            ..b.clone()
        }),
        other => other.clone(),
    }
}

/// The vectors of versions 1 and 2 (`tests/vectors/v1/`, `v2/`, frozen when
/// each was current) still decode, to the same records with `end_trim =
/// None` (and, in version 1, `threshold_hold = threshold_int`: one
/// threshold), with the same loss accounting. Every payload but
/// StreamStart's is the same in all versions: a lone non-start frame differs
/// from the current encoder's only in the version byte and the CRC.
#[test]
fn older_version_vectors_still_decode() {
    for version in [1u8, 2] {
        let dir = format!("v{version}");
        for (file, packets) in vectors() {
            let path = vector_dir().join(&dir).join(file);
            let text = std::fs::read_to_string(&path)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let bytes = parse_hex(&text);
            let want: Vec<(u32, Record)> = packets
                .iter()
                .map(|(seq, r)| (*seq, as_older_version(r, version)))
                .collect();
            let d = decode_all(&bytes);
            let got: Vec<(u32, Record)> =
                d.packets.into_iter().map(|p| (p.seq, p.record)).collect();
            assert_eq!(got, want, "{dir}/{file}");
            assert_eq!(d.stats.malformed + d.stats.newer_version, 0, "{dir}/{file}");
            assert_eq!(
                d.stats.lost_in_transport, packets[0].0 as u64,
                "{dir}/{file}"
            );
            if !matches!(want[0].1, Record::Start(_)) && want.len() == 1 {
                let now = encode(&want[0].1, want[0].0);
                assert_eq!(bytes.len(), now.len(), "{dir}/{file}");
                assert_eq!(bytes[2], version);
                assert_eq!(now[2], VERSION);
                assert_eq!(
                    bytes[3..bytes.len() - 4],
                    now[3..now.len() - 4],
                    "{dir}/{file}"
                );
            }
        }
    }
    // A StreamStart of another version's length is malformed.
    let v3 = encode(&Record::Start(vector_start()), 0);
    for version in [1u8, 2] {
        let mut as_old = v3.clone();
        as_old[2] = version;
        let crc = smartagg_model::packet::crc32c(&as_old[..as_old.len() - 4]);
        let n = as_old.len();
        as_old[n - 4..].copy_from_slice(&crc.to_le_bytes());
        assert!(decode_frame(&as_old).is_err());
    }
    assert!(decode_frame(&v3).is_ok());
    // A StreamStart read from an older stream cannot be written as version 3.
    let old = as_older_version(&Record::Start(vector_start()), 2);
    let mut out = Vec::new();
    assert_eq!(
        encode_record(&old, 0, &mut out),
        Err(smartagg_model::packet::PacketError::NoEndTrim)
    );
    assert!(out.is_empty());
}

#[test]
fn hex_vectors_cover_the_format() {
    let all: Vec<Record> = vectors()
        .into_iter()
        .flat_map(|(_, p)| p)
        .map(|(_, r)| r)
        .collect();
    for kind in [0x01u8, 0x02, 0x03, 0x04, 0x7F] {
        assert!(all
            .iter()
            .any(|r| smartagg_model::packet::type_of(r) == kind));
    }
    let edge = vector_blink_edge();
    assert!(edge.has(flags::EDGE) && edge.roi_x0() < 0 && edge.roi_y0() < 0 && edge.t_s < 0);
    // The large vector exercises a 5-byte varint and an escape code.
    let large = vector_blink_large();
    let (base, k, _) = rice::choose(&large.counts);
    assert_eq!(rice::varint_len(base), 5);
    assert!(large
        .counts
        .iter()
        .any(|&c| ((c - base) >> k) >= rice::ESCAPE_Q));
}

// ---------------------------------------------------------------- compression

/// Pixel-integrated Gaussian weight of pixel (x, y) for a PSF centred at
/// (cx, cy), by 8×8 sub-pixel sampling.
fn psf_weight(x: usize, y: usize, cx: f64, cy: f64, sigma: f64) -> f64 {
    let mut w = 0.0;
    for i in 0..8 {
        for j in 0..8 {
            let dx = x as f64 + (i as f64 + 0.5) / 8.0 - cx;
            let dy = y as f64 + (j as f64 + 0.5) / 8.0 - cy;
            w += (-(dx * dx + dy * dy) / (2.0 * sigma * sigma)).exp();
        }
    }
    w / 64.0 / (2.0 * std::f64::consts::PI * sigma * sigma)
}

/// Simulated blink ROIs (R×R, centre pixel R/2): background Bin(n_planes,
/// p_bg) per pixel, plus on-planes where the pixel fires with probability
/// 1 − (1 − p_bg)·exp(−λ·w) for a molecule giving λ detections per plane.
fn simulate_rois(seed: u64, n_rois: usize, r: usize) -> Vec<Vec<u32>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let p_bg = 0.0118;
    let lambda = 0.455;
    let sigma = 1.5;
    let n_window = 108; // pre-roll: planes summed with the molecule off
    (0..n_rois)
        .map(|_| {
            // 10-100 ms blinks at 100 us planes.
            let n_on: u64 = rng.gen_range(100..=1000);
            let cx = r as f64 / 2.0 + rng.gen_range(-0.5..0.5);
            let cy = r as f64 / 2.0 + rng.gen_range(-0.5..0.5);
            let off = Binomial::new(n_window, p_bg).unwrap();
            (0..r * r)
                .map(|i| {
                    let w = psf_weight(i % r, i / r, cx, cy, sigma);
                    let p_on = 1.0 - (1.0 - p_bg) * (-lambda * w).exp();
                    let on = Binomial::new(n_on, p_on).unwrap();
                    (off.sample(&mut rng) + on.sample(&mut rng)) as u32
                })
                .collect()
        })
        .collect()
}

#[test]
fn roi_compression_is_close_to_entropy() {
    let rois = simulate_rois(2024, 400, 9);
    let mut hist: HashMap<u32, u64> = HashMap::new();
    let mut n = 0u64;
    let mut block_bits = 0u64;
    let mut packet_bytes = 0u64;
    for (i, roi) in rois.iter().enumerate() {
        for &c in roi {
            *hist.entry(c).or_default() += 1;
            n += 1;
        }
        let mut block = Vec::new();
        rice::encode_counts(roi, &mut block);
        assert_eq!(rice::decode_counts(&block, roi.len()).unwrap(), *roi);
        block_bits += 8 * block.len() as u64;
        let rec = Record::Blink(BlinkRecord {
            counts: roi.clone(),
            ..blink(9, vec![])
        });
        packet_bytes += encode(&rec, i as u32).len() as u64;
    }
    let h0: f64 = hist
        .values()
        .map(|&m| {
            let p = m as f64 / n as f64;
            -p * p.log2()
        })
        .sum();
    let ratio = block_bits as f64 / (h0 * n as f64);
    println!(
        "ROI compression: order-0 entropy {h0:.3} bits/count, count blocks {:.3} bits/count \
         (base, k and padding included), ratio {ratio:.3}; mean Blink packet {:.1} bytes \
         (raw u32 counts would be {} bytes of counts)",
        block_bits as f64 / n as f64,
        packet_bytes as f64 / rois.len() as f64,
        81 * 4
    );
    assert!(
        ratio < 1.2,
        "count blocks use {ratio:.3}x the order-0 entropy"
    );
    // The simulation is what it claims to be: background plus a PSF bump.
    let centre: f64 = rois.iter().map(|r| r[40] as f64).sum::<f64>() / rois.len() as f64;
    let corner: f64 = rois.iter().map(|r| r[0] as f64).sum::<f64>() / rois.len() as f64;
    assert!(
        centre > 3.0 * corner && corner > 1.0,
        "centre {centre}, corner {corner}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 2000,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Count blocks round trip, fit the worst-case bound, and their length is
    /// predicted exactly.
    #[test]
    fn count_blocks_round_trip(counts in (0u8..=15).prop_flat_map(|h| arb_counts(2 * h + 1))) {
        let mut block = Vec::new();
        rice::encode_counts(&counts, &mut block);
        prop_assert_eq!(block.len(), rice::encoded_len(&counts));
        prop_assert!(block.len() <= rice::max_encoded_len(counts.len()));
        prop_assert_eq!(rice::decode_counts(&block, counts.len()), Ok(counts));
    }

    /// Arbitrary bytes never panic the count decoder; what it accepts is
    /// a valid block of those counts.
    #[test]
    fn count_decoder_survives_garbage(bytes in prop::collection::vec(any::<u8>(), 0..200),
                                      n in 0usize..100) {
        if let Ok(counts) = rice::decode_counts(&bytes, n) {
            prop_assert_eq!(counts.len(), n);
            let mut block = Vec::new();
            rice::encode_counts(&counts, &mut block);
            prop_assert_eq!(rice::decode_counts(&block, n), Ok(counts));
        }
    }
}

/// Payloads built by hand from the offsets in PACKETS.md equal the encoder's.
#[test]
fn layouts_match_the_written_definition() {
    let o = Record::Overflow(OverflowRecord {
        first_seq: 42,
        count: 7,
    });
    assert_eq!(
        encode(&o, 42),
        raw_frame(VERSION, 0x7F, 42, &[42, 0, 0, 0, 7, 0, 0, 0])
    );
    let d = Record::Dropped(vector_dropped());
    let mut p = vec![0xBC, 0x9A, 0x78, 0x56, 0x34, 0x12, 3, 0, 0, 0];
    p.extend_from_slice(&[0x2C, 0x01, 17, 0]);
    assert_eq!(encode(&d, 4), raw_frame(VERSION, 0x03, 4, &p));
    let e = Record::End(vector_end());
    let p: Vec<u8> = [600_000u64, 1_234, 56_789, 12, 345, 6]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    assert_eq!(encode(&e, 5), raw_frame(VERSION, 0x04, 5, &p));
    let s = vector_start();
    let mut p = Vec::new();
    p.extend_from_slice(&320u16.to_le_bytes());
    p.extend_from_slice(&240u16.to_le_bytes());
    for v in [108u32, 1_234_567, 3, 10_000] {
        p.extend_from_slice(&v.to_le_bytes());
    }
    p.extend_from_slice(&[1, 32, 9, 8, 7]);
    for w in &s.kernel {
        p.extend_from_slice(&w.to_le_bytes());
    }
    p.extend_from_slice(&100_000u32.to_le_bytes());
    p.extend_from_slice(&5u32.to_le_bytes());
    // Version 2: threshold_hold after masked_pixels; version 3: end_trim.
    p.extend_from_slice(&654_321u32.to_le_bytes());
    p.extend_from_slice(&54u32.to_le_bytes());
    assert_eq!(
        encode(&Record::Start(s), 0),
        raw_frame(VERSION, 0x01, 0, &p)
    );
    // Blink: fixed fields, then the count block of a 1x1 ROI with count 5:
    // base 5, k = 0, the single code bit "0" padded to a byte: 05 00 00.
    let b = Record::Blink(BlinkRecord {
        slot: 7,
        flags: flags::EDGE,
        anchor_x: 0x0102,
        anchor_y: 0x0304,
        t_cross: 0x0A0B_0C0D_0E0F,
        t_drop: 1,
        t_s: -2,
        t_e: 3,
        planes_summed: 0x1122_3344,
        roi_size: 1,
        counts: vec![5],
    });
    let mut p = vec![7, 0x01, 0x02, 0x01, 0x04, 0x03];
    p.extend_from_slice(&[0x0F, 0x0E, 0x0D, 0x0C, 0x0B, 0x0A]);
    p.extend_from_slice(&[1, 0, 0, 0, 0, 0]);
    p.extend_from_slice(&[0xFE, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF]);
    p.extend_from_slice(&[3, 0, 0, 0, 0, 0]);
    p.extend_from_slice(&[0x44, 0x33, 0x22, 0x11, 1]);
    p.extend_from_slice(&[5, 0, 0]);
    assert_eq!(encode(&b, 9), raw_frame(VERSION, 0x02, 9, &p));
}
