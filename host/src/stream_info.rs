//! Where a `.rois` stream came from: the sidecar `FILE.rois.json` that
//! `aggregate` and `download` write beside the stream, so that `localize`
//! needs no camera flags.
//!
//! The packet stream itself (model/PACKETS.md) carries the sensor size and
//! the pipeline's configuration, not the optics: a gateware design does not
//! know which objective sits in front of the sensor. The sidecar records the
//! camera preset and objective the stream was made with, and the pixel size
//! and PSF width that follow from them, as plain JSON a user can read or
//! edit (say, for another objective). Explicit `localize` flags win over it.

use anyhow::{bail, Context};
use serde::{Deserialize, Serialize};
use smartagg_model::params::{Preset, PresetName};
use std::path::{Path, PathBuf};

/// The `format` field of every sidecar.
pub const FORMAT: &str = "smartagg-stream-info";
/// The sidecar version this build writes and reads.
pub const VERSION: u32 = 1;

/// What `localize` needs to know about a stream that the stream does not say.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StreamInfo {
    /// Always [`FORMAT`].
    pub format: String,
    /// Always [`VERSION`].
    pub version: u32,
    /// Camera preset the stream was made for (`smartagg presets`).
    pub camera: String,
    /// Objective magnification.
    pub objective: u32,
    /// Sample-plane pixel size, nm.
    pub pixel_nm: f64,
    /// PSF standard deviation, camera pixels.
    pub psf_sigma_px: f64,
    /// Sensor width, pixels (as in the stream's StreamStart).
    pub width: u32,
    /// Sensor height, pixels (as in the stream's StreamStart).
    pub height: u32,
    /// The command that wrote the stream, with this program's version.
    pub written_by: String,
}

impl StreamInfo {
    /// The sidecar for a stream made with `preset` on a `width × height` sensor.
    pub fn new(preset: &Preset, width: u32, height: u32, command: &str) -> StreamInfo {
        StreamInfo {
            format: FORMAT.into(),
            version: VERSION,
            camera: preset.name.as_str().into(),
            objective: preset.optics.magnification as u32,
            pixel_nm: preset.pixel_nm(),
            psf_sigma_px: preset.sigma_px(),
            width,
            height,
            written_by: format!("smartagg {command} {}", env!("CARGO_PKG_VERSION")),
        }
    }

    /// Where the sidecar of `stream` lives: the stream's name plus `.json`.
    pub fn path_for(stream: &Path) -> PathBuf {
        let mut name = stream.as_os_str().to_owned();
        name.push(".json");
        PathBuf::from(name)
    }

    /// Writes the sidecar of `stream` atomically.
    pub fn write_beside(&self, stream: &Path) -> anyhow::Result<PathBuf> {
        let path = StreamInfo::path_for(stream);
        let mut text = serde_json::to_string_pretty(self)?;
        text.push('\n');
        smartagg_io::output::write_atomic(&path, text.as_bytes())?;
        Ok(path)
    }

    /// Reads the sidecar of `stream`, if there is one, and checks it.
    pub fn read_beside(stream: &Path) -> anyhow::Result<Option<(StreamInfo, PathBuf)>> {
        let path = StreamInfo::path_for(stream);
        let text = match std::fs::read(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
        };
        let hint = "give the camera with --preset or --pixel-nm instead";
        if text.len() > 64 * 1024 {
            bail!(
                "{} is not a stream sidecar (over 64 KiB); {hint}",
                path.display()
            );
        }
        let info: StreamInfo = serde_json::from_slice(&text)
            .with_context(|| format!("{} is not a valid stream sidecar; {hint}", path.display()))?;
        info.check()
            .with_context(|| format!("{}: {hint}", path.display()))?;
        Ok(Some((info, path)))
    }

    fn check(&self) -> anyhow::Result<()> {
        if self.format != FORMAT {
            bail!("format is {:?}, not {FORMAT:?}", self.format);
        }
        if self.version != VERSION {
            bail!(
                "sidecar version {} (this build reads version {VERSION})",
                self.version
            );
        }
        if !(self.pixel_nm.is_finite() && (0.1..=1e6).contains(&self.pixel_nm)) {
            bail!(
                "pixel_nm must be between 0.1 and 1e6 nm, got {}",
                self.pixel_nm
            );
        }
        if !(self.psf_sigma_px.is_finite() && (0.05..=100.0).contains(&self.psf_sigma_px)) {
            bail!(
                "psf_sigma_px must be between 0.05 and 100 pixels, got {}",
                self.psf_sigma_px
            );
        }
        if self.width == 0 || self.height == 0 {
            bail!("the sensor is {}x{}", self.width, self.height);
        }
        Ok(())
    }

    /// The preset named in the sidecar, if this build knows it (a hand-made
    /// sidecar may name another camera; its pixel size and PSF still count).
    pub fn preset(&self) -> Option<Preset> {
        let name = PresetName::parse(&self.camera).ok()?;
        Preset::new(name, self.objective).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info() -> StreamInfo {
        let p = Preset::new(PresetName::Spcimager, 150).unwrap();
        StreamInfo::new(&p, 320, 240, "aggregate")
    }

    #[test]
    fn round_trips_beside_the_stream() {
        let dir = tempfile::tempdir().unwrap();
        let stream = dir.path().join("blinks.rois");
        let written = info().write_beside(&stream).unwrap();
        assert_eq!(written, dir.path().join("blinks.rois.json"));
        let (back, path) = StreamInfo::read_beside(&stream).unwrap().unwrap();
        assert_eq!(back, info());
        assert_eq!(path, written);
        assert!(
            (back.pixel_nm - 8000.0 / 150.0).abs() < 1e-9,
            "{}",
            back.pixel_nm
        );
        assert_eq!(back.preset().unwrap().name, PresetName::Spcimager);
    }

    #[test]
    fn no_sidecar_is_none() {
        let dir = tempfile::tempdir().unwrap();
        assert!(StreamInfo::read_beside(&dir.path().join("x.rois"))
            .unwrap()
            .is_none());
    }

    #[test]
    fn bad_sidecars_are_refused_with_the_way_out() {
        let dir = tempfile::tempdir().unwrap();
        let stream = dir.path().join("x.rois");
        let side = StreamInfo::path_for(&stream);
        let cases: Vec<(String, &str)> = vec![
            ("not json".into(), "not a valid stream sidecar"),
            (
                serde_json::to_string(&StreamInfo {
                    pixel_nm: f64::MAX,
                    ..info()
                })
                .unwrap(),
                "pixel_nm",
            ),
            (
                serde_json::to_string(&StreamInfo {
                    psf_sigma_px: 0.0,
                    ..info()
                })
                .unwrap(),
                "psf_sigma_px",
            ),
            (
                serde_json::to_string(&StreamInfo {
                    version: 9,
                    ..info()
                })
                .unwrap(),
                "version 9",
            ),
            (
                serde_json::to_string(&StreamInfo {
                    format: "other".into(),
                    ..info()
                })
                .unwrap(),
                "format",
            ),
        ];
        for (text, want) in cases {
            std::fs::write(&side, &text).unwrap();
            let e = format!("{:#}", StreamInfo::read_beside(&stream).unwrap_err());
            assert!(e.contains(want), "{text}: {e}");
            assert!(e.contains("--preset"), "{e}");
        }
    }
}
