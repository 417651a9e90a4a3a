//! The second decoder, `tools/rois.py` (written from `model/PACKETS.md`
//! alone), against the host's: `python3 tools/rois.py FILE` and
//! `smartagg inspect FILE --json` must print the same bytes — on the frozen
//! vectors, on random streams from the model's encoder, on a stream of the
//! golden pipeline, and on corrupted variants of them all (flipped bytes,
//! truncation, inserted garbage, duplicated, deleted and swapped packets,
//! CRC-valid malformed and newer-version frames).
//!
//! python3 is required (`scripts/setup.sh` installs it): without it this
//! test fails, it does not skip.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smartagg_model::config::PipelineConfig;
use smartagg_model::packet::{crc32c, Encoder};
use smartagg_model::pipeline;
use smartagg_model::plane::BitPlane;
use smartagg_model::record::{
    BlinkRecord, DroppedRecord, OverflowRecord, Record, StreamEnd, StreamStart,
};
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The bytes of a `.hex` test vector: `#` comments, whitespace ignored.
fn hex_bytes(text: &str) -> Vec<u8> {
    let digits: String = text
        .lines()
        .map(|l| l.split('#').next().unwrap())
        .flat_map(|l| l.chars().filter(|c| !c.is_whitespace()))
        .collect();
    assert!(digits.len().is_multiple_of(2), "odd number of hex digits");
    (0..digits.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&digits[i..i + 2], 16).expect("hex digits"))
        .collect()
}

/// Runs both decoders on `bytes` and asserts identical, successful output.
fn same_output(name: &str, bytes: &[u8], dir: &Path) -> String {
    let file = dir.join("stream.rois");
    std::fs::write(&file, bytes).unwrap();
    let rust = Command::new(env!("CARGO_BIN_EXE_smartagg"))
        .arg("inspect")
        .arg(&file)
        .arg("--json")
        .output()
        .expect("the smartagg binary runs");
    assert!(
        rust.status.success(),
        "{name}: smartagg inspect failed: {}",
        String::from_utf8_lossy(&rust.stderr)
    );
    let py = match Command::new("python3")
        .arg(repo().join("tools/rois.py"))
        .arg(&file)
        .output()
    {
        Ok(o) => o,
        Err(e) => panic!(
            "python3 is required by this test (tools/rois.py) and could not be run: {e}; \
             install it (scripts/setup.sh does)"
        ),
    };
    assert!(
        py.status.success(),
        "{name}: tools/rois.py failed: {}",
        String::from_utf8_lossy(&py.stderr)
    );
    let (r, p) = (
        String::from_utf8(rust.stdout).expect("utf-8"),
        String::from_utf8(py.stdout).expect("utf-8"),
    );
    if r != p {
        let line = r
            .lines()
            .zip(p.lines())
            .position(|(a, b)| a != b)
            .unwrap_or(r.lines().count().min(p.lines().count()));
        panic!(
            "{name}: the decoders differ at line {line} ({} bytes of input)\n  rust:   {}\n  python: {}",
            bytes.len(),
            r.lines().nth(line).unwrap_or("<end>"),
            p.lines().nth(line).unwrap_or("<end>")
        );
    }
    r
}

fn vectors() -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for sub in [
        "model/tests/vectors",
        "model/tests/vectors/v2",
        "model/tests/vectors/v1",
    ] {
        let mut files: Vec<PathBuf> = std::fs::read_dir(repo().join(sub))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "hex"))
            .collect();
        files.sort();
        assert!(files.len() >= 8, "vectors missing in {sub}");
        for f in files {
            let text = std::fs::read_to_string(&f).unwrap();
            out.push((
                format!("{sub}/{}", f.file_name().unwrap().to_string_lossy()),
                hex_bytes(&text),
            ));
        }
    }
    out
}

/// Counts of a random ROI: background-like, a bump, or wide values.
fn counts(rng: &mut ChaCha8Rng, r: u8) -> Vec<u32> {
    let n = r as usize * r as usize;
    match rng.gen_range(0..4) {
        0 => (0..n).map(|_| rng.gen_range(0..6)).collect(),
        1 => {
            let base = rng.gen_range(0..1000);
            (0..n)
                .map(|i| {
                    base + if i == n / 2 {
                        300
                    } else {
                        rng.gen_range(0..20)
                    }
                })
                .collect()
        }
        2 => (0..n).map(|_| rng.gen()).collect(),
        _ => vec![rng.gen_range(0..3); n],
    }
}

/// A random stream as separate packets: StreamStart, random Blinks and
/// Dropped, some announced losses (Overflow in place of the records), and
/// usually a StreamEnd.
fn random_packets(rng: &mut ChaCha8Rng) -> Vec<Vec<u8>> {
    let r = [1u8, 3, 5, 9, 31][rng.gen_range(0..5)];
    let klen = rng.gen_range(0..8usize) * 2 + 1;
    let start = StreamStart {
        width: rng.gen(),
        height: rng.gen(),
        n_window: rng.gen(),
        threshold_int: rng.gen(),
        threshold_hold: rng.gen(),
        end_trim: Some(rng.gen()),
        l_min: rng.gen(),
        l_max: rng.gen(),
        r_assoc: rng.gen(),
        slots: rng.gen(),
        roi_size: r,
        kernel_shift: rng.gen(),
        kernel: (0..klen).map(|_| rng.gen()).collect(),
        plane_period_ns: rng.gen(),
        masked_pixels: rng.gen(),
    };
    let mut records = vec![Record::Start(start)];
    for _ in 0..rng.gen_range(0..25) {
        records.push(if rng.gen_bool(0.8) {
            let t_cross = rng.gen_range(0..1u64 << 48);
            let t_drop = rng.gen_range(0..1u64 << 48);
            Record::Blink(BlinkRecord {
                slot: rng.gen(),
                flags: rng.gen(),
                anchor_x: rng.gen(),
                anchor_y: rng.gen(),
                t_cross,
                t_drop,
                t_s: rng.gen_range(-(1i64 << 47)..1i64 << 47),
                t_e: rng.gen_range(-(1i64 << 47)..1i64 << 47),
                planes_summed: rng.gen(),
                roi_size: r,
                counts: counts(rng, r),
            })
        } else {
            Record::Dropped(DroppedRecord {
                plane: rng.gen_range(0..1u64 << 48),
                count: rng.gen(),
                first_x: rng.gen(),
                first_y: rng.gen(),
            })
        });
    }
    if rng.gen_bool(0.9) {
        records.push(Record::End(StreamEnd {
            planes: rng.gen(),
            blinks: rng.gen(),
            unconfirmed: rng.gen(),
            dropped_candidates: rng.gen(),
            bridged_dips: rng.gen(),
            cut_segments: rng.gen(),
        }));
    }
    // Encode, and lose runs of records on the "device": each run becomes
    // one Overflow packet in its place.
    let mut enc = if rng.gen_bool(0.2) {
        // Close to the sequence number's wrap.
        Encoder::starting_at(u32::MAX - rng.gen_range(0..5))
    } else {
        Encoder::new()
    };
    let mut packets = Vec::new();
    let mut lost: Option<(u32, u32)> = None;
    for (i, rec) in records.iter().enumerate() {
        let seq = enc.next_seq();
        let mut bytes = Vec::new();
        enc.push(rec, &mut bytes).expect("encodable");
        let droppable = i > 0 && !matches!(rec, Record::End(_));
        if droppable && rng.gen_bool(0.1) {
            lost = Some(match lost {
                Some((f, n)) => (f, n + 1),
                None => (seq, 1),
            });
            continue;
        }
        if let Some((first_seq, count)) = lost.take() {
            let mut ov = Vec::new();
            enc.push(
                &Record::Overflow(OverflowRecord { first_seq, count }),
                &mut ov,
            )
            .unwrap();
            packets.push(ov);
        }
        packets.push(bytes);
    }
    packets
}

/// A stream of the golden pipeline: a few blinking spots on a small field,
/// short L_max (cuts, continuations, empty segments), few slots (drops).
fn pipeline_packets(rng: &mut ChaCha8Rng) -> Vec<Vec<u8>> {
    let (w, h) = (12usize, 10usize);
    let mut cfg = PipelineConfig::new(w, h, 4, vec![1, 2, 1], 2, 24);
    cfg.threshold_hold = 12;
    cfg.slots = 3;
    cfg.roi_size = 3;
    cfg.l_min = 2;
    cfg.l_max = 6;
    let spots: Vec<(usize, usize)> = (0..4)
        .map(|_| (rng.gen_range(0..w), rng.gen_range(0..h)))
        .collect();
    let planes: Vec<BitPlane> = (0..rng.gen_range(20..80))
        .map(|t| {
            let on: Vec<bool> = spots
                .iter()
                .enumerate()
                .map(|(i, _)| (t / (3 + i)) % 3 != 0)
                .collect();
            let mut r = ChaCha8Rng::seed_from_u64(t as u64 * 7919 + 1);
            BitPlane::from_fn(w, h, |x, y| {
                spots.iter().zip(&on).any(|(&(sx, sy), &o)| {
                    o && x.abs_diff(sx) <= 1 && y.abs_diff(sy) <= 1 && r.gen_bool(0.8)
                }) || r.gen_bool(0.02)
            })
        })
        .collect();
    let records = pipeline::run(cfg, planes).expect("pipeline runs");
    let mut enc = Encoder::new();
    records
        .iter()
        .map(|rec| {
            let mut b = Vec::new();
            enc.push(rec, &mut b).unwrap();
            b
        })
        .collect()
}

/// Rewrites a packet's header and payload and gives it a valid CRC.
fn reframe(packet: &[u8], edit: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    let mut body = packet[..packet.len() - 4].to_vec();
    edit(&mut body);
    let len = (body.len() - 10) as u16;
    body[8..10].copy_from_slice(&len.to_le_bytes());
    let crc = crc32c(&body);
    body.extend_from_slice(&crc.to_le_bytes());
    body
}

/// Corrupted variants of a stream given as packets.
fn variants(
    rng: &mut ChaCha8Rng,
    packets: &[Vec<u8>],
    turn: usize,
) -> Vec<(&'static str, Vec<u8>)> {
    let whole: Vec<u8> = packets.concat();
    let mut out = Vec::new();
    if whole.is_empty() {
        return out;
    }
    let mut flipped = whole.clone();
    for _ in 0..rng.gen_range(1..6) {
        let i = rng.gen_range(0..flipped.len());
        flipped[i] ^= 1 << rng.gen_range(0..8);
    }
    out.push(("flipped bits", flipped));
    let mut changed = whole.clone();
    let i = rng.gen_range(0..changed.len());
    changed[i] = rng.gen();
    out.push(("changed byte", changed));
    out.push(("truncated", whole[..rng.gen_range(0..whole.len())].to_vec()));
    // Garbage, with magic and header fragments, inserted anywhere.
    let mut garbage = whole.clone();
    for _ in 0..rng.gen_range(1..4) {
        let mut g: Vec<u8> = (0..rng.gen_range(1..40)).map(|_| rng.gen()).collect();
        if rng.gen_bool(0.5) {
            g.extend_from_slice(&[0x53, 0x41, rng.gen_range(0..4), rng.gen_range(0..5)]);
        }
        let at = rng.gen_range(0..=garbage.len());
        garbage.splice(at..at, g);
    }
    out.push(("inserted garbage", garbage));
    // A short header, or a frame cut by the end, after garbage.
    let mut tail = whole.clone();
    tail.extend_from_slice(&[0x00, 0x53, 0x41, 0x02, 0x02]);
    out.push(("short header at the end", tail));
    let mut p = packets.to_vec();
    let k = rng.gen_range(0..p.len());
    let dup = p[k].clone();
    let at = rng.gen_range(k..=p.len());
    p.insert(at, dup);
    out.push(("duplicated packet", p.concat()));
    if packets.len() > 2 {
        let mut p = packets.to_vec();
        let k = rng.gen_range(1..p.len());
        p.remove(k);
        out.push(("deleted packet", p.concat()));
        let mut p = packets.to_vec();
        let (a, b) = (rng.gen_range(0..p.len()), rng.gen_range(0..p.len()));
        p.swap(a, b);
        out.push(("swapped packets", p.concat()));
        let mut p = packets.to_vec();
        p.insert(1, packets[0].clone());
        out.push(("second StreamStart", p.concat()));
    }
    // CRC-valid frames that must be skipped (one kind per stream, in turn):
    // newer version, unknown type, wrong length, even ROI side, Overflow with
    // count 0, a broken count block or version 0.
    let mut p = packets.to_vec();
    let k = rng.gen_range(0..p.len());
    let victim = p[k].clone();
    let bad = match turn % 6 {
        0 => reframe(&victim, |b| b[2] = rng.gen_range(4..=255)),
        1 => reframe(&victim, |b| b[3] = 0x05),
        2 => reframe(&victim, |b| b.push(0)),
        3 => reframe(&victim, |b| {
            if b[3] == 0x02 {
                b[10 + 34] = 4;
            } else {
                b.pop();
            }
        }),
        4 => reframe(&victim, |b| {
            b[3] = 0x7F;
            let seq = [b[4], b[5], b[6], b[7]];
            b.truncate(10);
            b.extend_from_slice(&seq);
            b.extend_from_slice(&0u32.to_le_bytes());
        }),
        _ => reframe(&victim, |b| {
            if b[3] == 0x02 {
                // Padding or trailing data in the count block.
                let last = b.len() - 1;
                if b[last] & 1 == 0 && rng.gen_bool(0.5) {
                    b[last] |= 1;
                } else {
                    b.push(0);
                }
            } else {
                b[2] = 0;
            }
        }),
    };
    p[k] = bad;
    out.push(("CRC-valid bad frame", p.concat()));
    out
}

#[test]
fn python_decoder_equals_the_host_decoder() {
    let dir = tempfile::tempdir().unwrap();
    let mut cases = 0;
    let mut saw = std::collections::BTreeSet::new();
    let mut note = |out: &str| {
        for l in out.lines() {
            let t = l.split('"').nth(3).unwrap_or("").to_string();
            if t == "skipped" {
                saw.insert(
                    l.split("\"reason\":\"")
                        .nth(1)
                        .unwrap()
                        .split('"')
                        .next()
                        .unwrap()
                        .to_string(),
                );
            } else {
                saw.insert(t);
            }
        }
    };

    // The frozen vectors, each alone and all of a version in one stream.
    let vs = vectors();
    for (name, bytes) in &vs {
        note(&same_output(name, bytes, dir.path()));
        cases += 1;
    }
    for old in ["", "/v2/", "/v1/"] {
        let all: Vec<u8> = vs
            .iter()
            .filter(|(n, _)| {
                if old.is_empty() {
                    !n.contains("/v1/") && !n.contains("/v2/")
                } else {
                    n.contains(old)
                }
            })
            .flat_map(|(_, b)| b.clone())
            .collect();
        assert!(!all.is_empty());
        note(&same_output(
            &format!("all vectors {old}"),
            &all,
            dir.path(),
        ));
    }

    let mut rng = ChaCha8Rng::seed_from_u64(0x5A_2026);
    for i in 0..12 {
        let packets = if i % 4 == 1 {
            pipeline_packets(&mut rng)
        } else {
            random_packets(&mut rng)
        };
        let name = format!("stream {i}");
        note(&same_output(&name, &packets.concat(), dir.path()));
        cases += 1;
        for (what, bytes) in variants(&mut rng, &packets, i) {
            note(&same_output(&format!("{name}, {what}"), &bytes, dir.path()));
            cases += 1;
        }
    }
    // The corruptions reached every kind of event.
    for kind in [
        "stream_start",
        "blink",
        "dropped",
        "stream_end",
        "overflow",
        "gap",
        "corrupt",
        "malformed",
        "newer_version",
        "truncated",
        "summary",
    ] {
        assert!(saw.contains(kind), "no {kind} in {cases} cases: {saw:?}");
    }
}

#[test]
fn inspect_without_json_summarises() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(repo().join("model/tests/vectors/stream.hex")).unwrap();
    let file = dir.path().join("s.rois");
    std::fs::write(&file, hex_bytes(&text)).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_smartagg"))
        .arg("inspect")
        .arg(&file)
        .output()
        .unwrap();
    assert!(out.status.success());
    let s = String::from_utf8(out.stdout).unwrap();
    assert!(s.contains("records: 1 StreamStart, 2 Blink"), "{s}");
    assert!(s.contains("2 records lost on the device"), "{s}");
    assert!(s.contains("stream end: 600000 planes"), "{s}");
}
