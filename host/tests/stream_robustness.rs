//! `smartagg download` on damaged input, through the real binary: truncated,
//! zero-length and newer-version files give clear messages; a stalled source
//! ends after the timeout with the bytes received intact on disk. (The
//! million-corruption fuzzing of the download loop is a unit test of
//! `smartagg-transport`'s `fuzz_tests`, which needs the crate's internals.)

use smartagg_model::config::PipelineConfig;
use smartagg_model::packet::{crc32c, newer_version_message, HEADER_LEN};
use smartagg_model::packetiser::encode_stream;
use smartagg_model::record::{BlinkRecord, Record, StreamEnd};
use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn smartagg() -> Command {
    Command::new(env!("CARGO_BIN_EXE_smartagg"))
}

/// A small valid stream: start, six blinks, end.
fn stream() -> Vec<u8> {
    let cfg = PipelineConfig::new(40, 30, 10, vec![1, 2, 1], 2, 20);
    let mut records = vec![Record::Start(cfg.stream_start())];
    for i in 0..6u32 {
        records.push(Record::Blink(BlinkRecord {
            slot: i as u8,
            flags: 0,
            anchor_x: 5 + i as u16,
            anchor_y: 7,
            t_cross: 100 + i as u64,
            t_drop: 140 + i as u64,
            t_s: 95,
            t_e: 135,
            planes_summed: 50,
            roi_size: 3,
            counts: vec![2, 3, 2, 3, 10 + i, 3, 2, 3, 2],
        }));
    }
    records.push(Record::End(StreamEnd {
        planes: 300,
        blinks: 6,
        ..Default::default()
    }));
    encode_stream(&records).unwrap()
}

fn download(input: &Path, out: &Path, extra: &[&str]) -> Output {
    smartagg()
        .arg("download")
        .arg("--source")
        .arg(format!("file:{}", input.display()))
        .arg("--out")
        .arg(out)
        .arg("--quiet")
        .args(extra)
        .output()
        .unwrap()
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

#[test]
fn a_truncated_file_is_an_error_naming_the_truncation_and_kept_whole() {
    let dir = tempfile::tempdir().unwrap();
    let full = stream();
    let cut = full.len() - 20; // inside the stream-end packet
    let input = dir.path().join("cut.rois");
    std::fs::write(&input, &full[..cut]).unwrap();
    let out = dir.path().join("out.rois");
    let o = download(&input, &out, &[]);
    let t = text(&o);
    assert_eq!(o.status.code(), Some(2), "{t}");
    let tail = (14 + 48) - 20; // the stream-end frame, less the 20 bytes cut
    assert!(
        t.contains(&format!(
            "the stream is truncated: it ends inside a packet ({tail} bytes of an incomplete packet at the end)"
        )),
        "{t}"
    );
    assert!(t.contains("no stream-end record"), "{t}");
    assert!(
        t.contains(&format!(
            "all {cut} bytes received are in {}",
            out.display()
        )),
        "{t}"
    );
    assert!(t.contains("--allow-loss"), "{t}");
    assert_eq!(std::fs::read(&out).unwrap(), &full[..cut]);

    // Accepted with --allow-loss: the same facts as warnings, exit 0.
    let o = download(&input, &out, &["--allow-loss"]);
    let t = text(&o);
    assert_eq!(o.status.code(), Some(0), "{t}");
    assert!(t.contains("WARNING: the stream is truncated"), "{t}");
    assert!(t.contains("7 packets decoded"), "{t}");
}

#[test]
fn a_zero_length_file_is_an_error_even_with_allow_loss() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("empty.rois");
    std::fs::write(&input, b"").unwrap();
    let out = dir.path().join("out.rois");
    // An earlier output of that name survives a download that got nothing.
    std::fs::write(&out, b"earlier capture").unwrap();
    for extra in [&[][..], &["--allow-loss"][..]] {
        let o = download(&input, &out, extra);
        let t = text(&o);
        assert_eq!(o.status.code(), Some(2), "{t}");
        assert!(
            t.contains(&format!(
                "no data: file {} delivered 0 bytes",
                input.display()
            )),
            "{t}"
        );
        assert_eq!(std::fs::read(&out).unwrap(), b"earlier capture");
        assert!(!dir.path().join("out.rois.json").exists());
    }
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(names.len(), 2, "no partial file left behind: {names:?}");
}

/// The same packets re-labelled as format `version`, CRCs recomputed.
fn as_version(bytes: &[u8], version: u8) -> Vec<u8> {
    let mut out = Vec::new();
    let mut p = 0;
    while p < bytes.len() {
        let len = u16::from_le_bytes([bytes[p + 8], bytes[p + 9]]) as usize;
        let mut frame = bytes[p..p + HEADER_LEN + len].to_vec();
        frame[2] = version;
        let crc = crc32c(&frame);
        frame.extend_from_slice(&crc.to_le_bytes());
        out.extend_from_slice(&frame);
        p += HEADER_LEN + len + 4;
    }
    out
}

#[test]
fn a_stream_of_a_newer_format_version_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("v4.rois");
    let newer = as_version(&stream(), 4);
    std::fs::write(&input, &newer).unwrap();
    let out = dir.path().join("out.rois");
    for extra in [&[][..], &["--allow-loss"][..]] {
        let o = download(&input, &out, extra);
        let t = text(&o);
        assert_eq!(o.status.code(), Some(2), "{t}");
        assert!(t.contains(&newer_version_message(4)), "{t}");
        assert!(
            t.contains("8 packets could not be read; update smartagg"),
            "{t}"
        );
        assert!(
            t.contains(&format!("no valid packet in {} bytes", newer.len())),
            "{t}"
        );
        assert_eq!(
            std::fs::read(&out).unwrap(),
            newer,
            "the raw bytes are kept"
        );
    }

    // One newer packet inside a version-3 stream, before its stream-end
    // record: skipped and named.
    let mut mixed = stream();
    let v4 = as_version(&stream(), 4);
    let first_len = 14 + u16::from_le_bytes([v4[8], v4[9]]) as usize;
    let end_at = mixed.len() - (14 + 48);
    mixed.splice(end_at..end_at, v4[..first_len].iter().copied());
    std::fs::write(&input, &mixed).unwrap();
    let o = download(&input, &out, &[]);
    let t = text(&o);
    assert_eq!(o.status.code(), Some(2), "{t}");
    assert!(t.contains(&newer_version_message(4)), "{t}");
    assert!(
        t.contains("1 packets of a format version newer than 3 skipped"),
        "{t}"
    );
    let o = download(&input, &out, &["--allow-loss"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(text(&o).contains("WARNING: stream format version 4 is newer"));
}

#[test]
fn a_damaged_stream_reports_exact_losses_and_keeps_every_byte() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = stream();
    // Flip one bit inside the third packet (the second blink, seq 2).
    let start_len = 14 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let b1 = 14 + u16::from_le_bytes([bytes[start_len + 8], bytes[start_len + 9]]) as usize;
    bytes[start_len + b1 + 20] ^= 0x10;
    let input = dir.path().join("bad.rois");
    std::fs::write(&input, &bytes).unwrap();
    let out = dir.path().join("out.rois");
    let o = download(&input, &out, &["--allow-loss"]);
    let t = text(&o);
    assert_eq!(o.status.code(), Some(0), "{t}");
    assert!(t.contains("7 packets decoded"), "{t}");
    assert!(t.contains("1 records lost in transport"), "{t}");
    assert!(t.contains("1 CRC errors"), "{t}");
    assert!(t.contains("records 2..3 (1) lost in transport"), "{t}");
    assert_eq!(std::fs::read(&out).unwrap(), bytes);
}

/// A named pipe whose writer sends part of a stream and then goes quiet:
/// the download ends after the timeout, saying so, with the bytes on disk.
#[test]
fn a_stalled_source_ends_after_the_timeout_with_the_bytes_on_disk() {
    use std::io::Write;
    use std::os::unix::fs::OpenOptionsExt;
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("live.rois");
    let st = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(st.success(), "mkfifo failed");
    let out = dir.path().join("out.rois");
    let mut child = smartagg()
        .args(["download", "--quiet", "--timeout", "0.2", "--source"])
        .arg(format!("file:{}", fifo.display()))
        .arg("--out")
        .arg(&out)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Open the write end without blocking (O_NONBLOCK, Linux value): it
    // succeeds once the child has opened the read end.
    let t0 = Instant::now();
    let mut writer = loop {
        match std::fs::OpenOptions::new()
            .write(true)
            .custom_flags(0o4000)
            .open(&fifo)
        {
            Ok(f) => break f,
            Err(_) if t0.elapsed() < Duration::from_secs(20) => {
                assert!(child.try_wait().unwrap().is_none(), "smartagg exited early");
                std::thread::sleep(Duration::from_millis(5));
            }
            Err(e) => panic!("the reader never opened the pipe: {e}"),
        }
    };
    let full = stream();
    let sent = &full[..full.len() / 2];
    writer.write_all(sent).unwrap();
    writer.flush().unwrap();
    // Keep the pipe open (no end of file) until smartagg gives up.
    let o = child.wait_with_output().unwrap();
    drop(writer);
    let t = text(&o);
    assert_eq!(o.status.code(), Some(2), "{t}");
    assert!(
        t.contains(&format!(
            "no data for 0.2 s from file {}; {} bytes received so far are in {}",
            fifo.display(),
            sent.len(),
            out.display()
        )),
        "{t}"
    );
    assert_eq!(std::fs::read(&out).unwrap(), sent);
    // The summary of what arrived is printed before the error.
    assert!(
        t.contains(&format!("{} bytes from file", sent.len())),
        "{t}"
    );
}
