//! Robustness of the download loop on corrupted streams: more than a million
//! random corruptions (bit flips, byte edits, bursts, insertions, deletions,
//! noise between packets, truncations) of realistic packet streams, delivered
//! in random chunks through [`download`] exactly as a device's bytes would be.
//!
//! For every stream it checks: no panic; the bytes written are exactly the
//! bytes the source produced; every corrupted packet is withheld and every
//! intact one delivered unchanged; the records lost in transport and on the
//! device are counted exactly; every input byte is accounted for.

use super::download::tests::{Collect, ScriptSource, Step};
use super::download::{download, DownloadOptions};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use smartagg_model::config::PipelineConfig;
use smartagg_model::packet::{
    crc32c, decode_frame, Encoder, Packet, CRC_LEN, HEADER_LEN, MAGIC, MAX_PAYLOAD,
};
use smartagg_model::pipeline::run;
use smartagg_model::plane::BitPlane;
use smartagg_model::record::{OverflowRecord, Record};
use std::time::Duration;

/// Records of the golden pipeline on a small random scene: background
/// detections plus a few blinking emitters.
fn scene_records(seed: u64) -> Vec<Record> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (w, h) = (28usize, 22usize);
    let mut cfg = PipelineConfig::new(w, h, 6, vec![1, 2, 1], 2, 30);
    cfg.roi_size = 5;
    cfg.l_max = 60;
    cfg.slots = 8;
    // Emitters: position and on-intervals (planes).
    type Emitter = (usize, usize, Vec<(usize, usize)>);
    let emitters: Vec<Emitter> = (0..10)
        .map(|_| {
            let x = rng.gen_range(0..w);
            let y = rng.gen_range(0..h);
            let mut on = Vec::new();
            let mut t = rng.gen_range(0..40);
            while t < 700 {
                let len = rng.gen_range(8..90);
                on.push((t, t + len));
                t += len + rng.gen_range(20..200);
            }
            (x, y, on)
        })
        .collect();
    let planes: Vec<BitPlane> = (0..700)
        .map(|t| {
            BitPlane::from_fn(w, h, |x, y| {
                let lit = emitters.iter().any(|(ex, ey, on)| {
                    x.abs_diff(*ex) <= 1
                        && y.abs_diff(*ey) <= 1
                        && on.iter().any(|&(a, b)| (a..b).contains(&t))
                });
                rng.gen_bool(if lit { 0.6 } else { 0.01 })
            })
        })
        .collect();
    run(cfg, planes).expect("valid configuration")
}

/// One packet as the device sends it.
#[derive(Clone)]
struct Sent {
    bytes: Vec<u8>,
    packet: Packet,
    /// Records this packet stands for in loss accounting: 1, or an Overflow's count.
    weight: u64,
}

/// Every record of a scene encoded once: the encoder numbers records in
/// order whether or not the device later drops them, so each record's packet
/// is the same in every stream made from it.
struct Scene {
    packets: Vec<Sent>,
}

impl Scene {
    fn new(records: &[Record]) -> Scene {
        let mut enc = Encoder::new();
        let packets = records
            .iter()
            .map(|r| {
                let mut b = Vec::new();
                enc.push(r, &mut b).expect("encodable");
                Sent {
                    packet: decode_frame(&b).expect("valid"),
                    weight: 1,
                    bytes: b,
                }
            })
            .collect();
        Scene { packets }
    }
}

/// The gateware's stream for a scene: the model's packets with random runs
/// of records dropped by the output FIFO and announced by Overflow records
/// (never the first or the last record).
fn device_stream(scene: &Scene, rng: &mut ChaCha8Rng) -> Vec<Sent> {
    let n = scene.packets.len();
    let mut out = Vec::with_capacity(n + 8);
    let mut pending: Option<OverflowRecord> = None;
    for (i, p) in scene.packets.iter().enumerate() {
        if i > 0 && i + 1 < n && rng.gen_bool(0.04) {
            pending
                .get_or_insert(OverflowRecord {
                    first_seq: p.packet.seq,
                    count: 0,
                })
                .count += 1;
            continue;
        }
        if let Some(o) = pending.take() {
            let mut b = Vec::new();
            Encoder::new()
                .push(&Record::Overflow(o.clone()), &mut b)
                .expect("encodable");
            out.push(Sent {
                packet: decode_frame(&b).expect("valid"),
                weight: o.count as u64,
                bytes: b,
            });
        }
        out.push(p.clone());
    }
    out
}

/// Mutates `p` in place, always inside the packet (an insertion at its very
/// start would leave it intact). Returns false if the mutation changed nothing.
fn mutate(p: &mut Vec<u8>, rng: &mut ChaCha8Rng) -> bool {
    let before = p.clone();
    let len = p.len();
    match rng.gen_range(0..6) {
        0 => {
            let bit = rng.gen_range(0..len * 8);
            p[bit / 8] ^= 1 << (bit % 8);
        }
        1 => {
            for _ in 0..rng.gen_range(2..=8) {
                let bit = rng.gen_range(0..len * 8);
                p[bit / 8] ^= 1 << (bit % 8);
            }
        }
        2 => {
            let i = rng.gen_range(0..len);
            p[i] ^= rng.gen_range(1..=255u8);
        }
        3 => {
            let n = rng.gen_range(1..=32.min(len));
            let at = rng.gen_range(0..=len - n);
            rng.fill(&mut p[at..at + n]);
        }
        4 => {
            let at = rng.gen_range(1..len);
            let n = rng.gen_range(1..=16);
            let noise: Vec<u8> = (0..n).map(|_| rng.gen()).collect();
            p.splice(at..at, noise);
        }
        _ => {
            let n = rng.gen_range(1..=8.min(len - 1));
            let at = rng.gen_range(0..=len - n);
            p.drain(at..at + n);
        }
    }
    *p != before
}

#[derive(Default)]
struct Tally {
    streams: u64,
    corruptions: u64,
    corrupted_packets: u64,
    bytes: u64,
}

impl std::ops::Add for Tally {
    type Output = Tally;
    fn add(self, o: Tally) -> Tally {
        Tally {
            streams: self.streams + o.streams,
            corruptions: self.corruptions + o.corruptions,
            corrupted_packets: self.corrupted_packets + o.corrupted_packets,
            bytes: self.bytes + o.bytes,
        }
    }
}

/// The CRC-valid frames of `stream`, scanning byte by byte and consuming a
/// frame whole when its CRC matches (the rule of PACKETS.md §6, written
/// plainly, without the incremental decoder's buffering).
fn crc_valid_frames(stream: &[u8]) -> Vec<&[u8]> {
    let mut frames = Vec::new();
    let mut p = 0;
    while p + HEADER_LEN + CRC_LEN <= stream.len() {
        let h = &stream[p..];
        let len = u16::from_le_bytes([h[8], h[9]]) as usize;
        let total = HEADER_LEN + len + CRC_LEN;
        let plausible = h[..2] == MAGIC && h[2] != 0 && len <= MAX_PAYLOAD;
        if plausible && total <= h.len() {
            let crc = u32::from_le_bytes(h[total - CRC_LEN..total].try_into().unwrap());
            if crc32c(&h[..total - CRC_LEN]) == crc {
                frames.push(&h[..total]);
                p += total;
                continue;
            }
        }
        p += 1;
    }
    frames
}

/// One corrupted stream through the download loop, with every check.
fn trial(pool: &[Scene], seed: u64) -> Tally {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let sent = device_stream(&pool[rng.gen_range(0..pool.len())], &mut rng);
    let mut t = Tally {
        streams: 1,
        ..Default::default()
    };
    // Corrupt some packets (1–3 mutations each), sprinkle noise between packets.
    let p_corrupt = rng.gen_range(0.05..0.6);
    let mut stream = Vec::new();
    for s in &sent {
        if rng.gen_bool(0.05) {
            let n = rng.gen_range(1..=24);
            stream.extend((0..n).map(|_| rng.gen::<u8>()));
            t.corruptions += 1;
        }
        let mut b = s.bytes.clone();
        if rng.gen_bool(p_corrupt) {
            for _ in 0..rng.gen_range(1..=3) {
                if mutate(&mut b, &mut rng) {
                    t.corruptions += 1;
                }
            }
            if b == s.bytes {
                // Rare: the mutations cancelled out. Make it a real corruption.
                b[0] ^= 0x01;
                t.corruptions += 1;
            }
        }
        stream.extend_from_slice(&b);
    }
    // Sometimes truncate the stream (a capture cut short).
    if rng.gen_bool(0.25) {
        let cut = rng.gen_range(0..stream.len());
        stream.truncate(cut);
        t.corruptions += 1;
    }
    t.bytes = stream.len() as u64;

    // Which sent packets are still in the stream, whole and unchanged? A
    // mutation can leave a packet whole (noise inserted right after its last
    // byte is noise between packets), so ask the stream itself, with the
    // plain resynchronisation rule of PACKETS.md §6. Every CRC-valid frame
    // in it must be one of the packets sent, in order: anything else would be
    // an undetected corruption.
    let mut arrived: Vec<usize> = Vec::new();
    for frame in crc_valid_frames(&stream) {
        let from = arrived.last().map_or(0, |&i| i + 1);
        let Some(k) = (from..sent.len()).find(|&i| sent[i].bytes == frame) else {
            panic!("seed {seed}: a corrupted frame passed the CRC: {frame:02x?}");
        };
        arrived.push(k);
    }
    t.corrupted_packets = (sent.len() - arrived.len()) as u64;
    let last = arrived.last().copied();
    let (mut want_transport, mut want_device) = (0u64, 0u64);
    for (i, s) in sent.iter().enumerate() {
        if arrived.binary_search(&i).is_ok() {
            if matches!(s.packet.record, Record::Overflow(_)) {
                want_device += s.weight;
            }
        } else if last.is_some_and(|l| i < l) {
            // Missing before the last delivered packet: a counted gap.
            want_transport += s.weight;
        }
    }

    // Deliver in random chunks with idle reads between, as a device would.
    let mut steps = Vec::new();
    let mut at = 0;
    while at < stream.len() {
        let n = rng.gen_range(1..=4096).min(stream.len() - at);
        steps.push(Step::Data(stream[at..at + n].to_vec()));
        if rng.gen_bool(0.1) {
            steps.push(Step::Idle);
        }
        at += n;
    }
    steps.push(Step::End);
    let mut src = ScriptSource::new(steps, false);
    let opts = DownloadOptions {
        stall_timeout: Duration::from_secs(30),
        chunk_size: rng.gen_range(1..=8192),
        ..Default::default()
    };
    let mut obs = Collect::default();
    let mut out: Vec<u8> = Vec::new();
    let report = download(&mut src, &mut out, "fuzz.rois", &opts, &mut obs)
        .unwrap_or_else(|f| panic!("seed {seed}: {f}"));

    assert!(
        out == stream,
        "seed {seed}: the bytes on disk differ from the source's"
    );
    let want: Vec<&Packet> = arrived.iter().map(|&i| &sent[i].packet).collect();
    let got: Vec<&Packet> = obs.packets.iter().collect();
    assert!(
        got == want,
        "seed {seed}: delivered {} packets, expected {} intact ones",
        got.len(),
        want.len()
    );
    let s = &report.stats;
    assert_eq!(s.lost_in_transport, want_transport, "seed {seed}: {s}");
    assert_eq!(s.lost_on_device, want_device, "seed {seed}: {s}");
    assert_eq!(s.out_of_order, 0, "seed {seed}: {s}");
    let delivered_bytes: u64 = arrived.iter().map(|&i| sent[i].bytes.len() as u64).sum();
    assert_eq!(
        s.bytes_in,
        delivered_bytes + s.bytes_skipped + s.truncated_tail_bytes,
        "seed {seed}: every byte accounted for"
    );
    assert_eq!(s.bytes_in, stream.len() as u64);
    // Complete exactly when nothing was changed and the device dropped nothing.
    let untouched = stream.len() == sent.iter().map(|s| s.bytes.len()).sum::<usize>()
        && arrived.len() == sent.len();
    assert_eq!(
        report.complete(),
        untouched && want_device == 0,
        "seed {seed}: {:?}",
        report.problems()
    );
    t
}

/// More than 1,000,000 corruptions in all (the figure is printed; run with
/// `--nocapture` to see it).
#[test]
fn a_million_corruptions_through_the_download_loop_are_all_detected_and_counted() {
    let records: Vec<Vec<Record>> = (0..6).into_par_iter().map(scene_records).collect();
    for r in &records {
        let blinks = r.iter().filter(|r| matches!(r, Record::Blink(_))).count();
        assert!(
            blinks >= 15,
            "the scenes must produce realistic streams ({blinks} blinks)"
        );
    }
    let pool: Vec<Scene> = records.iter().map(|r| Scene::new(r)).collect();
    let mut total = Tally::default();
    let mut batch = 0u64;
    while total.corruptions < 1_000_000 {
        let base = batch * 1024;
        total = total
            + (base..base + 1024)
                .into_par_iter()
                .map(|seed| trial(&pool, seed))
                .reduce(Tally::default, |a, b| a + b);
        batch += 1;
    }
    println!(
        "{} corruptions in {} corrupted packets of {} streams ({} MB) through the download loop: all detected, losses exact",
        total.corruptions,
        total.corrupted_packets,
        total.streams,
        total.bytes as f64 / 1e6
    );
    assert!(total.corruptions >= 1_000_000);
}

/// A few corrupted streams through a real file on disk: the file holds
/// exactly the bytes received.
#[test]
fn corrupted_streams_reach_the_file_on_disk_unchanged() {
    let scene = Scene::new(&scene_records(99));
    let dir = tempfile::tempdir().unwrap();
    for seed in 0..20u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut stream: Vec<u8> = device_stream(&scene, &mut rng)
            .into_iter()
            .flat_map(|s| s.bytes)
            .collect();
        for _ in 0..50 {
            let i = rng.gen_range(0..stream.len());
            stream[i] ^= rng.gen_range(1..=255u8);
        }
        let path = dir.path().join(format!("s{seed}.rois"));
        let mut file = std::fs::File::create(&path).unwrap();
        let chunks = stream.chunks(777).map(|c| Step::Data(c.to_vec()));
        let mut src = ScriptSource::new(chunks.chain([Step::End]).collect(), false);
        let r = download(
            &mut src,
            &mut file,
            "f",
            &DownloadOptions::default(),
            &mut Collect::default(),
        )
        .unwrap();
        drop(file);
        assert_eq!(std::fs::read(&path).unwrap(), stream);
        assert!(!r.complete());
        assert!(r.stats.crc_errors + r.stats.bytes_skipped > 0);
    }
}
