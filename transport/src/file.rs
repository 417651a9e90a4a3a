//! A recorded packet stream as a source: a `.rois` file, or anything that can
//! be opened for reading (a named pipe fed by another program).
//!
//! A reader thread does the blocking reads and hands chunks over a bounded
//! channel, so [`FileSource::read`] can give up after its wait even when the
//! underlying `read` blocks (a named pipe whose writer went quiet): that is
//! how a stalled source is detected. `--rate-mbps` paces the delivery to
//! simulate a device.
//!
//! Hostile inputs (issue 36): a named pipe or device is opened by the
//! reader thread, not by [`FileSource::open`], so a FIFO nobody writes to
//! cannot block the command in `open()` past its `--timeout`; a directory
//! is refused at once; and a source whose first [`NOT_A_STREAM_AFTER`]
//! bytes hold no valid packet (`/dev/zero`, a disk image) ends with an error
//! instead of being copied for ever.

use super::{Chunk, DeviceConfig, PacketSource, TransportError};
use smartagg_model::packet::{Decoder, Event};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

/// Bytes per chunk the reader thread reads.
const READ_CHUNK: usize = 1 << 16;

/// A source delivering this many bytes without a single valid packet is not
/// a packet stream (a real stream starts with its StreamStart packet; even a
/// capture joined mid-stream has a packet within 4 KiB).
pub const NOT_A_STREAM_AFTER: u64 = 4 << 20;

/// Slowest and fastest `--rate-mbps`, MB (10⁶ bytes) per second.
pub const RATE_MBPS_RANGE: (f64, f64) = (1e-3, 1e5);

/// What the reader thread sends.
enum Msg {
    Data(Vec<u8>),
    Error(std::io::Error),
}

/// Reads a byte stream from any reader, with time-limited reads.
pub struct FileSource {
    label: String,
    path: PathBuf,
    reader: Option<Box<dyn Read + Send>>,
    /// A pipe or device to open in the reader thread (see the module docs).
    open_later: Option<PathBuf>,
    /// Looks for a first valid packet; `None` once one was found.
    sniffer: Option<Decoder>,
    rx: Option<Receiver<Msg>>,
    /// Bytes received from the thread but not yet handed out.
    pending: Vec<u8>,
    pending_at: usize,
    /// Bytes per second, if paced.
    rate: Option<f64>,
    started: Option<Instant>,
    delivered: u64,
    stopped: bool,
    ended: bool,
}

impl FileSource {
    /// Opens `path` for reading. Nothing is read until [`PacketSource::start`].
    /// A directory is refused; a named pipe, socket or device is opened by the
    /// reader thread once started, so that waiting for its writer honours
    /// the caller's timeout.
    pub fn open(path: &Path) -> Result<FileSource, TransportError> {
        let io = |error| TransportError::Io {
            path: path.to_path_buf(),
            error,
        };
        let meta = std::fs::metadata(path).map_err(io)?;
        if meta.is_dir() {
            return Err(io(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "is a directory, not a packet stream (give a .rois file or a named pipe)",
            )));
        }
        if !meta.is_file() {
            let mut src = Self::from_reader(
                format!("file {}", path.display()),
                path,
                Box::new(std::io::empty()),
            );
            src.reader = None;
            src.open_later = Some(path.to_path_buf());
            return Ok(src);
        }
        let file = std::fs::File::open(path).map_err(io)?;
        Ok(Self::from_reader(
            format!("file {}", path.display()),
            path,
            Box::new(file),
        ))
    }

    /// A source over any reader (tests, pipes); `path` names it in errors.
    pub fn from_reader(label: String, path: &Path, reader: Box<dyn Read + Send>) -> FileSource {
        FileSource {
            label,
            path: path.to_path_buf(),
            reader: Some(reader),
            open_later: None,
            sniffer: Some(Decoder::new()),
            rx: None,
            pending: Vec::new(),
            pending_at: 0,
            rate: None,
            started: None,
            delivered: 0,
            stopped: false,
            ended: false,
        }
    }

    /// Paces delivery at `mb_per_s` megabytes (10⁶ bytes) per second, as a
    /// device would. Rates outside [`RATE_MBPS_RANGE`] are refused.
    pub fn with_rate(mut self, mb_per_s: f64) -> Result<FileSource, TransportError> {
        let (lo, hi) = RATE_MBPS_RANGE;
        if !(mb_per_s.is_finite() && (lo..=hi).contains(&mb_per_s)) {
            return Err(TransportError::Config(format!(
                "--rate-mbps must be a number in {lo} ..= {hi} MB/s (10^6 bytes per second), not {}",
                smartagg_model::params::fmt_num(mb_per_s)
            )));
        }
        self.rate = Some(mb_per_s * 1e6);
        Ok(self)
    }

    /// Bytes the pacing allows now (unbounded without `--rate-mbps`), and how
    /// long until one more byte is allowed.
    fn allowance(&self) -> (usize, Duration) {
        let (Some(rate), Some(t0)) = (self.rate, self.started) else {
            return (usize::MAX, Duration::ZERO);
        };
        let budget = rate * t0.elapsed().as_secs_f64() - self.delivered as f64;
        if budget >= 1.0 {
            (budget.min(usize::MAX as f64) as usize, Duration::ZERO)
        } else {
            let wait = Duration::try_from_secs_f64((1.0 - budget) / rate)
                .unwrap_or(Duration::from_secs(1));
            (0, wait)
        }
    }

    fn take_pending(&mut self, buf: &mut [u8], limit: usize) -> Result<usize, TransportError> {
        let n = (self.pending.len() - self.pending_at)
            .min(buf.len())
            .min(limit);
        buf[..n].copy_from_slice(&self.pending[self.pending_at..self.pending_at + n]);
        self.pending_at += n;
        self.delivered += n as u64;
        self.sniff(&buf[..n])?;
        Ok(n)
    }

    /// Until a first valid packet is seen: refuses a source that delivered
    /// [`NOT_A_STREAM_AFTER`] bytes without one.
    fn sniff(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        let Some(d) = &mut self.sniffer else {
            return Ok(());
        };
        d.feed(bytes);
        while let Some(e) = d.next_event() {
            if matches!(e, Event::Packet(_)) {
                self.sniffer = None;
                return Ok(());
            }
        }
        if self.delivered >= NOT_A_STREAM_AFTER {
            self.stopped = true;
            self.rx = None;
            return Err(TransportError::Io {
                path: self.path.clone(),
                error: std::io::Error::new(
                    std::io::ErrorKind::InvalidData,
                    format!(
                        "not a packet stream: no valid packet in its first {} bytes ({} MiB)",
                        self.delivered,
                        NOT_A_STREAM_AFTER >> 20
                    ),
                ),
            });
        }
        Ok(())
    }
}

impl PacketSource for FileSource {
    fn describe(&self) -> String {
        self.label.clone()
    }

    fn is_device(&self) -> bool {
        false
    }

    fn configure(&mut self, _cfg: &DeviceConfig) -> Result<(), TransportError> {
        // A recording carries its configuration in its StreamStart records.
        Ok(())
    }

    fn start(&mut self) -> Result<(), TransportError> {
        let later = self.open_later.take();
        let reader = self.reader.take();
        if reader.is_none() && later.is_none() {
            return Ok(());
        }
        // Small bound: the thread reads ahead a few chunks, no more.
        let (tx, rx) = mpsc::sync_channel(4);
        std::thread::spawn(move || {
            let mut reader = match (reader, later) {
                (Some(r), _) => r,
                // May block until a writer opens the pipe: `read` gives up
                // after its wait meanwhile.
                (None, Some(path)) => match std::fs::File::open(path) {
                    Ok(f) => Box::new(f) as Box<dyn Read + Send>,
                    Err(e) => {
                        let _ = tx.send(Msg::Error(e));
                        return;
                    }
                },
                (None, None) => return,
            };
            loop {
                let mut chunk = vec![0u8; READ_CHUNK];
                match reader.read(&mut chunk) {
                    Ok(0) => break,
                    Ok(n) => {
                        chunk.truncate(n);
                        if tx.send(Msg::Data(chunk)).is_err() {
                            break;
                        }
                    }
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                    Err(e) => {
                        let _ = tx.send(Msg::Error(e));
                        break;
                    }
                }
            }
        });
        self.rx = Some(rx);
        self.started = Some(Instant::now());
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], wait: Duration) -> Result<Chunk, TransportError> {
        if self.stopped || self.ended || buf.is_empty() {
            return Ok(if buf.is_empty() {
                Chunk::Idle
            } else {
                Chunk::End
            });
        }
        let deadline = Instant::now() + wait;
        let (mut allowed, until) = self.allowance();
        if allowed == 0 {
            std::thread::sleep(until.min(wait));
            allowed = self.allowance().0;
            if allowed == 0 {
                return Ok(Chunk::Idle);
            }
        }
        if self.pending_at < self.pending.len() {
            return Ok(Chunk::Data(self.take_pending(buf, allowed)?));
        }
        let Some(rx) = &self.rx else {
            return Err(TransportError::Config(
                "file source read before start".into(),
            ));
        };
        match rx.recv_timeout(deadline.saturating_duration_since(Instant::now())) {
            Ok(Msg::Data(chunk)) => {
                self.pending = chunk;
                self.pending_at = 0;
                Ok(Chunk::Data(self.take_pending(buf, allowed)?))
            }
            Ok(Msg::Error(error)) => Err(TransportError::Io {
                path: self.path.clone(),
                error,
            }),
            Err(RecvTimeoutError::Timeout) => Ok(Chunk::Idle),
            Err(RecvTimeoutError::Disconnected) => {
                self.ended = true;
                Ok(Chunk::End)
            }
        }
    }

    fn stop(&mut self) -> Result<(), TransportError> {
        // Dropping the receiver ends the reader thread at its next chunk.
        self.stopped = true;
        self.rx = None;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drain(src: &mut FileSource, buf_len: usize) -> Vec<u8> {
        let mut out = Vec::new();
        let mut buf = vec![0u8; buf_len];
        loop {
            match src.read(&mut buf, Duration::from_secs(5)).unwrap() {
                Chunk::Data(n) => out.extend_from_slice(&buf[..n]),
                Chunk::Idle => {}
                Chunk::End => return out,
            }
        }
    }

    #[test]
    fn delivers_every_byte_in_order_whatever_the_buffer_size() {
        let data: Vec<u8> = (0..200_000u32).map(|i| (i * 7 + i / 300) as u8).collect();
        for buf_len in [1, 13, 4096, 1 << 20] {
            let mut src = FileSource::from_reader(
                "mem".into(),
                Path::new("mem"),
                Box::new(std::io::Cursor::new(data.clone())),
            );
            src.start().unwrap();
            assert_eq!(drain(&mut src, buf_len), data, "buffer {buf_len}");
        }
    }

    #[test]
    fn pacing_limits_each_read_to_the_rate() {
        let data = vec![0x55u8; 100_000];
        // 0.01 MB/s = 10 kB/s: 100 ms of waiting allows about 1 kB.
        let mut src = FileSource::from_reader(
            "mem".into(),
            Path::new("mem"),
            Box::new(std::io::Cursor::new(data)),
        )
        .with_rate(0.01)
        .unwrap();
        src.start().unwrap();
        let mut buf = vec![0u8; 65536];
        let mut got = 0;
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_millis(100) {
            if let Chunk::Data(n) = src.read(&mut buf, Duration::from_millis(20)).unwrap() {
                got += n;
            }
        }
        // Never more than the rate allows by the time of the last read.
        let allowed = 10_000.0 * t0.elapsed().as_secs_f64() + 1.0;
        assert!(got as f64 <= allowed, "{got} bytes > {allowed}");
        assert!(got > 0);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e-100, 1e300] {
            let src =
                FileSource::from_reader("mem".into(), Path::new("mem"), Box::new(std::io::empty()));
            let e = src.with_rate(bad).err().unwrap().to_string();
            assert!(
                e.contains("--rate-mbps must be a number in 0.001 ..= 100000 MB/s"),
                "{e}"
            );
        }
    }

    #[test]
    fn stop_ends_the_stream_and_missing_files_are_named() {
        let mut src = FileSource::from_reader(
            "mem".into(),
            Path::new("mem"),
            Box::new(std::io::Cursor::new(vec![1u8; 10])),
        );
        src.start().unwrap();
        src.stop().unwrap();
        let mut buf = [0u8; 4];
        assert_eq!(src.read(&mut buf, Duration::ZERO).unwrap(), Chunk::End);
        assert!(!src.is_device());

        let e = FileSource::open(Path::new("/nonexistent/x.rois"))
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("/nonexistent/x.rois") && e.contains("No such file"),
            "{e}"
        );
    }
}
