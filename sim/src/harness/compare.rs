//! The comparison of the gateware's packet stream with the model's: the
//! stream split into packets, a lossy stream checked against the model's
//! (every gap announced by one exact Overflow record), the StreamStart's
//! MASKED_PIXELS, and the pipe-out's end padding removed.

use smartagg_model::packet::decode_all;
use smartagg_model::record::Record;

/// One packet of a byte stream: its header sequence number, its record and
/// its bytes (header to CRC).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Framed<'a> {
    /// Header sequence number (an Overflow's `first_seq`).
    pub seq: u32,
    /// The decoded record.
    pub record: Record,
    /// The packet's bytes.
    pub bytes: &'a [u8],
}

/// Splits a packet stream into its packets, back to back from the first
/// byte to the last, every one with a valid CRC and payload; or names the
/// byte at which that fails.
pub fn split_packets(bytes: &[u8]) -> Result<Vec<Framed<'_>>, String> {
    use smartagg_model::packet::{decode_frame, CRC_LEN, HEADER_LEN};
    let mut out = Vec::new();
    let mut p = 0;
    while p < bytes.len() {
        let rest = &bytes[p..];
        if rest.len() < HEADER_LEN {
            return Err(format!("byte {p}: {} bytes left, no packet", rest.len()));
        }
        let total = HEADER_LEN + u16::from_le_bytes([rest[8], rest[9]]) as usize + CRC_LEN;
        let frame = rest
            .get(..total)
            .ok_or_else(|| format!("byte {p}: a packet of {total} bytes runs past the end"))?;
        let packet = decode_frame(frame).map_err(|e| format!("byte {p}: {e}"))?;
        out.push(Framed {
            seq: packet.seq,
            record: packet.record,
            bytes: frame,
        });
        p += total;
    }
    Ok(out)
}

/// Whether the gateware's `bytes` are the model's stream `want` with
/// records lost on the device: split into packets, every packet but
/// Overflow byte-identical to the model's packet of the same sequence number
/// (the model's encoding of that record as its own packet), in order, and
/// every gap covered by exactly one Overflow record with the gap's first
/// sequence number and count, placed where the gap is (PACKETS.md §5);
/// nothing else. Ok(records lost) or what is wrong.
pub fn compare_lossy(bytes: &[u8], want: &[u8]) -> Result<u64, String> {
    let first = bytes.iter().zip(want).position(|(a, b)| a != b);
    let head = format!(
        "byte streams differ ({} bytes vs the model's {}, first difference at byte {:?})",
        bytes.len(),
        want.len(),
        first.or(Some(bytes.len().min(want.len())))
    );
    let got = split_packets(bytes).map_err(|e| format!("{head}; gateware stream: {e}"))?;
    let model = split_packets(want).map_err(|e| format!("{head}; model stream: {e}"))?;
    let base = model.first().map_or(0, |p| p.seq);
    // The model's packet of each sequence number, in order, none Overflow.
    for (i, m) in model.iter().enumerate() {
        if matches!(m.record, Record::Overflow(_)) || m.seq != base.wrapping_add(i as u32) {
            return Err(format!(
                "{head}; the model's packet {i} is not numbered in order"
            ));
        }
    }
    let index = |seq: u32| seq.wrapping_sub(base) as usize;
    let mut next = 0usize;
    let mut lost = 0u64;
    let mut after_overflow = false;
    for (k, g) in got.iter().enumerate() {
        match &g.record {
            Record::Overflow(o) => {
                if after_overflow {
                    return Err(format!("{head}; packet {k}: two Overflow records in a row"));
                }
                if index(o.first_seq) != next || o.count == 0 {
                    return Err(format!(
                        "{head}; packet {k}: Overflow of {} from seq {} where the next record is seq {}",
                        o.count,
                        o.first_seq,
                        base.wrapping_add(next as u32)
                    ));
                }
                next += o.count as usize;
                lost += o.count as u64;
                after_overflow = true;
            }
            _ => {
                let i = index(g.seq);
                if i != next {
                    return Err(format!(
                        "{head}; packet {k} has seq {} where seq {} is next (a gap no Overflow record announces, or out of order)",
                        g.seq,
                        base.wrapping_add(next as u32)
                    ));
                }
                let m = model.get(i).ok_or_else(|| {
                    format!(
                        "{head}; packet {k}: seq {} is past the model's stream",
                        g.seq
                    )
                })?;
                if g.bytes != m.bytes {
                    return Err(format!(
                        "{head}; packet {k} (seq {}) differs from the model's packet: gateware {:?}, model {:?} (bytes {:02x?} vs {:02x?})",
                        g.seq, g.record, m.record, g.bytes, m.bytes
                    ));
                }
                next += 1;
                after_overflow = false;
            }
        }
    }
    if next != model.len() || after_overflow {
        return Err(format!(
            "{head}; the stream accounts for {next} of the model's {} records{}",
            model.len(),
            if after_overflow {
                " and ends with an Overflow record"
            } else {
                ""
            }
        ));
    }
    if lost == 0 {
        return Err(format!("{head}; no Overflow record accounts for it"));
    }
    Ok(lost)
}

/// Whether the StreamStart the gateware sent first says MASKED_PIXELS =
/// the pixels of the mask loaded through pipe-in 0x81 (0 without
/// MASK_ENABLE), whatever the registers said.
pub(super) fn check_masked_pixels(packets: &[Framed], loaded: u32) -> Result<(), String> {
    match packets.first().map(|p| &p.record) {
        Some(Record::Start(s)) if s.masked_pixels == loaded => Ok(()),
        Some(Record::Start(s)) => Err(format!(
            "StreamStart says MASKED_PIXELS {} but the mask loaded through pipe-in 0x81 masks {loaded} pixels",
            s.masked_pixels
        )),
        other => Err(format!("the stream does not begin with StreamStart: {other:?}")),
    }
}

/// The plane of the first record that differs (its completion plane), for
/// back-half mismatches.
pub(super) fn first_differing_record_plane(bytes: &[u8], records: &[Record]) -> u64 {
    let d = decode_all(bytes);
    for (i, r) in records.iter().enumerate() {
        let got = d
            .packets
            .iter()
            .find(|p| p.seq as usize == i)
            .map(|p| &p.record);
        if got != Some(r) {
            return match r {
                Record::Blink(b) => b.t_drop,
                Record::Dropped(x) => x.plane,
                Record::End(e) => e.planes,
                _ => 0,
            };
        }
    }
    0
}

/// The packet bytes without the pipe-out's end padding: the shortest
/// prefix (at most 15 zero bytes removed) that decodes cleanly to a stream
/// ending with StreamEnd.
pub fn strip_padding(read: &[u8]) -> Vec<u8> {
    let zeros = read.iter().rev().take(15).take_while(|&&b| b == 0).count();
    for k in (0..=zeros).rev() {
        let cand = &read[..read.len() - k];
        let d = decode_all(cand);
        let s = &d.stats;
        if s.crc_errors + s.malformed + s.bytes_skipped + s.truncated_tail_bytes == 0
            && matches!(d.packets.last().map(|p| &p.record), Some(Record::End(_)))
        {
            return cand.to_vec();
        }
    }
    read.to_vec()
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use smartagg_model::config::PipelineConfig;
    use smartagg_model::packet::{crc32c, encode_record, BLINK_FIXED_LEN, HEADER_LEN};
    use smartagg_model::plane::BitPlane;
    use smartagg_model::record::OverflowRecord;

    /// A model stream with a few Blinks: its records and bytes.
    pub(crate) fn stream() -> (Vec<Record>, Vec<u8>) {
        let cfg = PipelineConfig::new(24, 12, 3, vec![1, 2, 1], 2, 8);
        let planes = (0..60).map(|t| {
            BitPlane::from_fn(24, 12, |x, y| {
                (t % 12 < 6 && x == 4 + t / 12 * 3 && y == 5) || (t % 12 >= 6 && x == 18 && y == 6)
            })
        });
        let records = smartagg_model::pipeline::run(cfg, planes).unwrap();
        assert!(
            records
                .iter()
                .filter(|r| matches!(r, Record::Blink(_)))
                .count()
                >= 4
        );
        let bytes = encode_stream(&records);
        (records, bytes)
    }

    pub(crate) fn encode_stream(records: &[Record]) -> Vec<u8> {
        smartagg_model::packetiser::encode_stream(records).unwrap()
    }

    /// The packets of `records` (numbered from 0) with records `lost` left
    /// out and announced by one Overflow record; `replace` swaps in other
    /// bytes for the packet of one sequence number.
    fn lossy(
        records: &[Record],
        lost: std::ops::Range<u32>,
        replace: Option<(u32, Vec<u8>)>,
    ) -> Vec<u8> {
        let mut out = Vec::new();
        for (i, r) in records.iter().enumerate() {
            let seq = i as u32;
            if seq == lost.start && !lost.is_empty() {
                let o = Record::Overflow(OverflowRecord {
                    first_seq: lost.start,
                    count: lost.len() as u32,
                });
                encode_record(&o, lost.start, &mut out).unwrap();
            }
            if lost.contains(&seq) {
                continue;
            }
            match &replace {
                Some((s, b)) if *s == seq => out.extend_from_slice(b),
                _ => encode_record(r, seq, &mut out).unwrap(),
            }
        }
        out
    }

    /// A packet re-framed around another payload (length and CRC fixed).
    fn reframe(packet: &[u8], payload: &[u8]) -> Vec<u8> {
        let mut p = packet[..HEADER_LEN].to_vec();
        p[8..10].copy_from_slice(&(payload.len() as u16).to_le_bytes());
        p.extend_from_slice(payload);
        let crc = crc32c(&p);
        p.extend_from_slice(&crc.to_le_bytes());
        p
    }

    /// A Rice count block with parameter `k` (PACKETS.md §4).
    fn rice_block(counts: &[u32], k: u8) -> Vec<u8> {
        let base = *counts.iter().min().unwrap();
        let mut out = Vec::new();
        let mut v = base;
        loop {
            let g = (v & 0x7f) as u8;
            v >>= 7;
            if v == 0 {
                out.push(g);
                break;
            }
            out.push(g | 0x80);
        }
        out.push(k);
        let mut bits = Vec::new();
        for &c in counts {
            let d = c - base;
            let q = d >> k;
            assert!(q < 32, "test counts stay below the escape");
            bits.extend(std::iter::repeat_n(true, q as usize));
            bits.push(false);
            bits.extend((0..k).rev().map(|i| d >> i & 1 != 0));
        }
        for chunk in bits.chunks(8) {
            let mut b = 0u8;
            for (i, &bit) in chunk.iter().enumerate() {
                b |= (bit as u8) << (7 - i);
            }
            out.push(b);
        }
        out
    }

    #[test]
    fn compare_lossy_takes_announced_losses_and_refuses_unannounced_ones() {
        let (records, want) = stream();
        let n = records.len() as u32;
        assert_eq!(compare_lossy(&lossy(&records, 2..4, None), &want), Ok(2));
        // Losses just before StreamEnd.
        assert_eq!(
            compare_lossy(&lossy(&records, n - 3..n - 1, None), &want),
            Ok(2)
        );
        // A gap with no Overflow record, a miscounted one, none at all.
        let mut silent = Vec::new();
        for (i, r) in records.iter().enumerate() {
            if i != 2 {
                encode_record(r, i as u32, &mut silent).unwrap();
            }
        }
        assert!(compare_lossy(&silent, &want).is_err());
        assert_eq!(compare_lossy(&lossy(&records, 2..5, None), &want), Ok(3));
        let mut miscounted = Vec::new();
        for (i, r) in records.iter().enumerate() {
            if i == 2 {
                let o = Record::Overflow(OverflowRecord {
                    first_seq: 2,
                    count: 3,
                });
                encode_record(&o, 2, &mut miscounted).unwrap();
            }
            if i != 2 && i != 3 {
                encode_record(r, i as u32, &mut miscounted).unwrap();
            }
        }
        assert!(compare_lossy(&miscounted, &want).is_err());
        assert!(
            compare_lossy(&want, &want).is_err(),
            "no loss is not a lossy stream"
        );
    }

    /// A surviving packet whose bytes differ from the model's but still
    /// decode with a valid CRC is refused: the same counts Rice-coded with
    /// another parameter (decoding to the very same record, so a comparison
    /// of records would pass it), and a count changed and re-encoded.
    #[test]
    fn compare_lossy_refuses_a_reencoded_packet_that_still_decodes() {
        let (records, want) = stream();
        let packets = split_packets(&want).unwrap();
        let (i, b) = records
            .iter()
            .enumerate()
            .find_map(|(i, r)| match r {
                Record::Blink(b) if i > 4 => Some((i, b.clone())),
                _ => None,
            })
            .expect("a Blink after the loss");
        let model = packets[i].bytes;
        let fixed = &model[HEADER_LEN..HEADER_LEN + BLINK_FIXED_LEN];
        let base = *b.counts.iter().min().unwrap();
        let k = model[HEADER_LEN + BLINK_FIXED_LEN + smartagg_model::rice::varint_len(base)];
        assert_eq!(
            k,
            smartagg_model::rice::choose(&b.counts).1,
            "the model's k"
        );
        // Another Rice parameter: the same record, other bytes.
        let mut payload = fixed.to_vec();
        payload.extend(rice_block(&b.counts, k + 1));
        let recoded = reframe(model, &payload);
        assert_ne!(recoded, model);
        let back = smartagg_model::packet::decode_frame(&recoded).expect("it decodes");
        assert_eq!(back.record, records[i], "the same record");
        assert_eq!(compare_lossy(&lossy(&records, 1..3, None), &want), Ok(2));
        let err = compare_lossy(&lossy(&records, 1..3, Some((i as u32, recoded))), &want)
            .expect_err("a re-encoded packet must be refused");
        assert!(err.contains(&format!("seq {i}")), "{err}");
        // A count changed: another record, a valid packet.
        let mut other = b.clone();
        other.counts[0] += 1;
        let mut changed = Vec::new();
        encode_record(&Record::Blink(other), i as u32, &mut changed).unwrap();
        assert!(smartagg_model::packet::decode_frame(&changed).is_ok());
        assert!(compare_lossy(&lossy(&records, 1..3, Some((i as u32, changed))), &want).is_err());
    }
}
