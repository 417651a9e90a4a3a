//! Stage 7 — packetiser: the records of the pipeline, in order, become the
//! byte stream of [`crate::packet`] (header, sequence number, payload with
//! Rice-coded ROI counts, CRC-32C). The gateware's packetiser must produce
//! exactly these bytes; `model/PACKETS.md` is the written definition.

use crate::packet::{Encoder, PacketError};
use crate::record::Record;

/// Turns records into packet bytes, numbering them from 0.
#[derive(Debug, Default)]
pub struct Packetiser {
    encoder: Encoder,
}

impl Packetiser {
    /// A packetiser at stream start (next sequence number 0).
    pub fn new() -> Packetiser {
        Packetiser {
            encoder: Encoder::new(),
        }
    }

    /// Appends the packet of `record` to `out`.
    pub fn push(&mut self, record: &Record, out: &mut Vec<u8>) -> Result<(), PacketError> {
        self.encoder.push(record, out)
    }

    /// Sequence number the next record will get.
    pub fn next_seq(&self) -> u32 {
        self.encoder.next_seq()
    }
}

/// The whole byte stream of a list of records.
pub fn encode_stream(records: &[Record]) -> Result<Vec<u8>, PacketError> {
    let mut p = Packetiser::new();
    let mut out = Vec::new();
    for r in records {
        p.push(r, &mut out)?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::PipelineConfig;
    use crate::packet::decode_all;
    use crate::pipeline::run;
    use crate::plane::BitPlane;

    #[test]
    fn pipeline_stream_decodes_back_to_its_records_without_loss() {
        let cfg = PipelineConfig::new(12, 10, 3, vec![1, 2, 1], 2, 8);
        let planes = (0..40)
            .map(|t| BitPlane::from_fn(12, 10, |x, y| (5..20).contains(&t) && x == 4 && y == 6));
        let records = run(cfg, planes).unwrap();
        assert!(records.iter().any(|r| matches!(r, Record::Blink(_))));
        let bytes = encode_stream(&records).unwrap();
        let decoded = decode_all(&bytes);
        assert!(!decoded.stats.any_loss(), "{}", decoded.stats);
        let back: Vec<Record> = decoded.packets.into_iter().map(|p| p.record).collect();
        assert_eq!(back, records);
    }
}
