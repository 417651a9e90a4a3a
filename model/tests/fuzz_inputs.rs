//! Fuzz-style tests of the readers of untrusted input (issue 36): the `.spad`
//! reader and the packet decoder get arbitrary bytes and mutations of valid
//! inputs (flipped bits, overwritten header fields, cuts, splices,
//! duplications). They must never panic, never allocate much more than the
//! input, and keep their accounting consistent.
//!
//! Plain proptest (no cargo-fuzz toolchain), so it runs with `cargo test`;
//! the case counts keep the whole file to a few seconds in a debug build.
//! Set `PROPTEST_CASES` to run longer.

use proptest::prelude::*;
use smartagg_model::packet::{
    decode_all, Decoder, Event, LossStats, SkipReason, CRC_LEN, HEADER_LEN, MAX_PACKET,
};
use smartagg_model::plane::BitPlane;
use smartagg_model::recording::{
    BitOrder, RecordingHeader, RecordingReader, RecordingWriter, PLANES_UNKNOWN,
};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

// ------------------------------------------------------- allocation meter

/// Counts the bytes allocated by the current thread (tests run on several
/// threads: each measures its own).
struct Meter;

thread_local! {
    static LIVE: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

fn note(delta: isize) {
    let _ = LIVE.try_with(|l| {
        let v = l.get() + delta;
        l.set(v);
        let _ = PEAK.try_with(|p| {
            if v > p.get() {
                p.set(v)
            }
        });
    });
}

unsafe impl GlobalAlloc for Meter {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note(layout.size() as isize);
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        note(-(layout.size() as isize));
        System.dealloc(ptr, layout)
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note(layout.size() as isize);
        System.alloc_zeroed(layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note(new_size as isize - layout.size() as isize);
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static METER: Meter = Meter;

/// Runs `f` and returns its result and the most bytes it held allocated at
/// once (beyond what was live when it started).
fn peak_alloc<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = LIVE.with(|l| l.get());
    PEAK.with(|p| p.set(base));
    let out = f();
    let peak = PEAK.with(|p| p.get());
    (out, (peak - base).max(0) as usize)
}

// ------------------------------------------------------------- .spad input

fn valid_recording(w: u32, h: u32, planes: u64, declared: u64, seed: u64) -> Vec<u8> {
    let header = RecordingHeader {
        width: w,
        height: h,
        plane_period_ns: 10_000,
        exposure_ns: 10_000,
        bit_order: if seed & 1 == 0 {
            BitOrder::LsbFirst
        } else {
            BitOrder::MsbFirst
        },
        planes: declared,
    };
    let mut wr = RecordingWriter::new(Vec::new(), header).unwrap();
    let mut s = seed | 1;
    for _ in 0..planes {
        let p = BitPlane::from_fn(w as usize, h as usize, |_, _| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s & 3 == 0
        });
        wr.write_plane(&p).unwrap();
    }
    wr.finish().unwrap()
}

/// Opens and reads a `.spad` (or raw planes) to the end or the first error;
/// checks the reader's promises and returns the planes read.
fn read_spad(bytes: &[u8], raw: Option<(u32, u32)>) -> u64 {
    let opened = match raw {
        None => RecordingReader::open(bytes),
        Some((w, h)) => RecordingReader::open_raw(bytes, w, h, BitOrder::LsbFirst, 1000),
    };
    let Ok(mut rd) = opened else {
        return 0;
    };
    let hd = *rd.header();
    assert!(hd.validate().is_ok(), "open returned an invalid header");
    let plane_bytes = hd.plane_bytes() as u64;
    let mut n = 0u64;
    loop {
        match rd.read_plane() {
            Ok(Some(p)) => {
                assert_eq!((p.width() as u32, p.height() as u32), (hd.width, hd.height));
                n += 1;
                assert!(
                    n * plane_bytes <= bytes.len() as u64,
                    "more planes than bytes"
                );
            }
            Ok(None) => break,
            Err(_) => {
                assert!(
                    rd.read_plane().unwrap().is_none(),
                    "reads go on after an error"
                );
                break;
            }
        }
    }
    if hd.planes != PLANES_UNKNOWN {
        assert!(n <= hd.planes, "more planes than declared");
    }
    assert_eq!(rd.planes_read(), n);
    n
}

/// A `.spad` reader never holds much more than the input (plus one small
/// plane's unpacking): a lying header allocates nothing sized by it.
fn check_spad(bytes: &[u8], raw: Option<(u32, u32)>) {
    let (_, peak) = peak_alloc(|| read_spad(bytes, raw));
    let bound = 4 * bytes.len() + (1 << 20);
    assert!(
        peak <= bound,
        "{peak} bytes allocated for {} input bytes",
        bytes.len()
    );
}

/// A header field to overwrite: (offset, width in bytes).
const SPAD_FIELDS: [(usize, usize); 8] = [
    (8, 2),
    (10, 2),
    (12, 4),
    (16, 4),
    (20, 8),
    (28, 8),
    (36, 1),
    (40, 8),
];

/// Interesting values for a header field of any width.
fn field_value() -> impl Strategy<Value = u64> {
    prop_oneof![
        any::<u64>(),
        Just(0u64),
        Just(1u64),
        Just(u64::MAX),
        Just(u32::MAX as u64),
        Just(u16::MAX as u64),
        Just(1u64 << 31),
        Just(32768u64),
        Just(65535u64),
        0u64..64,
    ]
}

#[derive(Debug, Clone)]
enum Mutation {
    Flip { at: usize, bit: u8 },
    Field { field: usize, value: u64 },
    Cut { at: usize },
    Insert { at: usize, bytes: Vec<u8> },
    Duplicate { from: usize, len: usize, to: usize },
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), 0u8..8).prop_map(|(at, bit)| Mutation::Flip { at, bit }),
        (0..SPAD_FIELDS.len(), field_value())
            .prop_map(|(field, value)| Mutation::Field { field, value }),
        any::<usize>().prop_map(|at| Mutation::Cut { at }),
        (any::<usize>(), prop::collection::vec(any::<u8>(), 1..32))
            .prop_map(|(at, bytes)| Mutation::Insert { at, bytes }),
        (any::<usize>(), 1usize..600, any::<usize>())
            .prop_map(|(from, len, to)| Mutation::Duplicate { from, len, to }),
    ]
}

/// Applies `m`; `fields` are the header fields (used by the `.spad` tests;
/// the packet tests pass none and a `Field` mutation flips a byte instead).
fn apply(b: &mut Vec<u8>, m: &Mutation, fields: &[(usize, usize)]) {
    if b.is_empty() {
        if let Mutation::Insert { bytes, .. } = m {
            b.extend_from_slice(bytes);
        }
        return;
    }
    let n = b.len();
    match m {
        Mutation::Flip { at, bit } => b[at % n] ^= 1 << bit,
        Mutation::Field { field, value } => {
            if fields.is_empty() {
                b[*value as usize % n] = (*field as u8).wrapping_mul(37);
                return;
            }
            let (o, w) = fields[field % fields.len()];
            if o + w <= n {
                b[o..o + w].copy_from_slice(&value.to_le_bytes()[..w]);
            }
        }
        Mutation::Cut { at } => b.truncate(at % (n + 1)),
        Mutation::Insert { at, bytes } => {
            let at = at % (n + 1);
            b.splice(at..at, bytes.iter().copied());
        }
        Mutation::Duplicate { from, len, to } => {
            let from = from % n;
            let len = (*len).min(n - from);
            let piece = b[from..from + len].to_vec();
            let to = to % (n + 1);
            b.splice(to..to, piece);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

    #[test]
    fn spad_reader_survives_arbitrary_bytes(
        bytes in prop::collection::vec(any::<u8>(), 0..600),
        magic: bool,
        raw_size in (1u32..100_000, 1u32..100_000),
        raw: bool,
    ) {
        let mut b = bytes;
        if magic && b.len() >= 8 {
            b[..8].copy_from_slice(b"SPADBITS");
        }
        if raw {
            check_spad(&b, Some(raw_size));
        } else {
            check_spad(&b, None);
        }
    }

    #[test]
    fn spad_reader_survives_mutated_recordings(
        (w, h) in (1u32..40, 1u32..24),
        planes in 0u64..5,
        unknown: bool,
        seed: u64,
        muts in prop::collection::vec(mutation(), 1..5),
    ) {
        let mut b = valid_recording(w, h, planes, if unknown { PLANES_UNKNOWN } else { planes }, seed);
        // Untouched, it reads back whole.
        prop_assert_eq!(read_spad(&b, None), planes);
        for m in &muts {
            apply(&mut b, m, &SPAD_FIELDS);
        }
        check_spad(&b, None);
        // The same bytes as raw planes of the header's size or another one.
        check_spad(&b, Some((w, h)));
        check_spad(&b, Some((w + 3, h)));
    }
}

#[test]
fn spad_headers_claiming_the_largest_planes_allocate_little() {
    for (w, h) in [
        (65535u32, 32768u32),
        (u32::MAX, 1),
        (1, u32::MAX),
        (46341, 46341),
    ] {
        for declared in [0, 1, 7, PLANES_UNKNOWN] {
            let mut b = valid_recording(4, 4, 0, 0, 1);
            b[12..16].copy_from_slice(&w.to_le_bytes());
            b[16..20].copy_from_slice(&h.to_le_bytes());
            b[40..48].copy_from_slice(&declared.to_le_bytes());
            for tail in [0usize, 1, 4048] {
                let mut c = b.clone();
                c.resize(48 + tail, 0xa5);
                check_spad(&c, None);
            }
        }
    }
}

// ---------------------------------------------------------- packet stream

fn stream_vector() -> Vec<u8> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/vectors/stream.hex");
    let text = std::fs::read_to_string(path).unwrap();
    let hex: String = text
        .lines()
        .map(|l| l.split('#').next().unwrap_or(""))
        .flat_map(|l| l.split_whitespace())
        .collect();
    (0..hex.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap())
        .collect()
}

/// Every event of a stream fed in `chunks`, then the counters.
fn decode_chunked(bytes: &[u8], chunks: &[usize]) -> (Vec<Event>, LossStats) {
    let mut d = Decoder::new();
    let mut events = Vec::new();
    let mut rest = bytes;
    let mut i = 0;
    while !rest.is_empty() {
        let n = if chunks.is_empty() {
            rest.len()
        } else {
            chunks[i % chunks.len()].clamp(1, rest.len())
        };
        i += 1;
        d.feed(&rest[..n]);
        rest = &rest[n..];
        assert!(d.buffered() <= smartagg_model::packet::DECODER_BUFFER);
        while let Some(e) = d.next_event() {
            events.push(e);
        }
    }
    events.extend(d.finish());
    (events, d.stats().clone())
}

/// The decoder's accounting: every byte is in a packet, skipped or the
/// truncated tail; the events agree with the counters.
fn check_accounting(bytes: &[u8], events: &[Event], st: &LossStats) {
    assert_eq!(st.bytes_in, bytes.len() as u64);
    let (mut packets, mut skipped, mut tail, mut lost_t, mut lost_d) =
        (0u64, 0u64, 0u64, 0u64, 0u64);
    let mut back = 0u64;
    for e in events {
        match e {
            Event::Packet(_) => packets += 1,
            Event::Skipped { bytes, reason } => {
                assert!(*bytes > 0, "empty skip");
                if *reason == SkipReason::Truncated {
                    tail += bytes
                } else {
                    skipped += bytes
                }
            }
            Event::Gap {
                lost, on_device, ..
            } => {
                if *lost == 0 {
                    back += 1;
                } else if *on_device {
                    lost_d += *lost as u64;
                } else {
                    lost_t += *lost as u64;
                }
            }
        }
    }
    assert_eq!(packets, st.packets_ok, "{st:?}");
    assert_eq!(skipped, st.bytes_skipped, "{st:?}");
    assert_eq!(tail, st.truncated_tail_bytes, "{st:?}");
    assert_eq!(lost_t, st.lost_in_transport, "{st:?}");
    assert_eq!(lost_d, st.lost_on_device, "{st:?}");
    assert_eq!(back, st.out_of_order, "{st:?}");
    // What is neither skipped nor tail was delivered in whole packets.
    let in_packets = st.bytes_in - st.bytes_skipped - st.truncated_tail_bytes;
    assert!(
        st.bytes_skipped + st.truncated_tail_bytes <= st.bytes_in,
        "{st:?}"
    );
    assert!(
        in_packets >= st.packets_ok * (HEADER_LEN + CRC_LEN) as u64,
        "{st:?}"
    );
    assert!(in_packets <= st.packets_ok * MAX_PACKET as u64, "{st:?}");
    assert!(
        st.crc_errors <= st.bytes_skipped + st.truncated_tail_bytes,
        "{st:?}"
    );
    if in_packets == 0 {
        assert_eq!(st.packets_ok, 0);
    }
}

/// Decodes `bytes` whole and in `chunks`: no panic, the same result either
/// way, consistent accounting and bounded memory.
fn check_stream(bytes: &[u8], chunks: &[usize]) {
    let (whole, peak) = peak_alloc(|| decode_all(bytes));
    // Decoded records may be larger than their compressed payloads (a
    // 31x31 ROI of counts, a 255-tap kernel): a fixed multiple of the input.
    let bound = 64 * bytes.len() + (256 << 10);
    assert!(
        peak <= bound,
        "decode_all held {peak} bytes for {} input bytes",
        bytes.len()
    );
    let (events, stats) = decode_chunked(bytes, chunks);
    check_accounting(bytes, &events, &stats);
    assert_eq!(whole.stats, stats, "the chunking changed the counters");
    let packets: Vec<_> = events
        .iter()
        .filter_map(|e| match e {
            Event::Packet(p) => Some(p.clone()),
            _ => None,
        })
        .collect();
    assert_eq!(whole.packets, packets, "the chunking changed the packets");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

    #[test]
    fn decoder_survives_arbitrary_bytes(
        bytes in prop::collection::vec(any::<u8>(), 0..3000),
        magic_every in 0usize..40,
        chunks in prop::collection::vec(1usize..5000, 0..6),
    ) {
        let mut b = bytes;
        // Sprinkle the magic so that the header path is exercised too.
        if magic_every > 1 {
            for i in (0..b.len().saturating_sub(1)).step_by(magic_every) {
                b[i] = 0x53;
                b[i + 1] = 0x41;
            }
        }
        check_stream(&b, &chunks);
    }

    #[test]
    fn decoder_survives_mutated_streams(
        copies in 1usize..4,
        muts in prop::collection::vec(mutation(), 0..8),
        chunks in prop::collection::vec(1usize..3000, 0..6),
    ) {
        let one = stream_vector();
        let mut b = Vec::new();
        for _ in 0..copies {
            b.extend_from_slice(&one);
        }
        for m in &muts {
            apply(&mut b, m, &[]);
        }
        check_stream(&b, &chunks);
    }
}

#[test]
fn the_stream_vector_decodes_whole() {
    let b = stream_vector();
    let d = decode_all(&b);
    assert_eq!(d.stats.bytes_skipped + d.stats.truncated_tail_bytes, 0);
    assert!(d.packets.len() >= 5, "{}", d.packets.len());
    check_stream(&b, &[1]);
    check_stream(&b, &[7, 1000]);
}
