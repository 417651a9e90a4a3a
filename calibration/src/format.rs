//! The calibration directory, version 1 (layout in the [module docs](super)).

use std::collections::BTreeMap;
use std::io::{BufReader, BufWriter, Write};
use std::path::{Component, Path, PathBuf};

use serde::{Deserialize, Serialize};
use smartagg_io::image::Pixels;
use smartagg_io::Samples;

use super::frames::{FrameCalibration, FrameCamera, FrameSummary};
use super::spad::{DarkSummary, FlatSummary, HotCriterion};
use super::{flags, AnyCalibration, Calibration, CalibrationError, Provenance};

/// `format` field of every calibration header.
pub const FORMAT: &str = "smartagg-calibration";
/// The newest format version this code reads, and the one it writes.
pub const VERSION: u32 = 1;
/// Name of the header file inside the calibration directory.
pub const HEADER_FILE: &str = "calibration.toml";

/// One map's entry in the header.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapEntry {
    /// File name inside the calibration directory.
    pub file: String,
    /// Sample type: `f32` or `u8`.
    pub sample: String,
    /// Unit of the values.
    pub unit: String,
    /// What the map holds.
    pub description: String,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct SpadHeader {
    tau_s: f64,
    plane_period_s: f64,
    planes: u64,
    dark: DarkSummary,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    flat: Option<FlatSummary>,
    hot_criterion: HotCriterion,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct Header {
    format: String,
    version: u32,
    kind: String,
    width: u32,
    height: u32,
    provenance: Provenance,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    spad: Option<SpadHeader>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    frame: Option<FrameSummary>,
    maps: BTreeMap<String, MapEntry>,
}

/// What values a map may hold.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Range {
    Finite,
    NonNegative,
    Positive,
    Flags,
}

#[derive(Debug, Clone, Copy)]
struct Spec {
    name: &'static str,
    unit: &'static str,
    description: &'static str,
    range: Range,
}

const fn spec(
    name: &'static str,
    unit: &'static str,
    description: &'static str,
    range: Range,
) -> Spec {
    Spec {
        name,
        unit,
        description,
        range,
    }
}

const DCR: Spec = spec(
    "dcr_hz",
    "Hz",
    "dark-count rate, -ln(1 - k/n)/tau (0 for NO_COUNTS, ln(2n)/tau lower estimate for SATURATED)",
    Range::NonNegative,
);
const DCR_SD: Spec = spec(
    "dcr_sd_hz",
    "Hz",
    "standard uncertainty of dcr_hz (delta method)",
    Range::NonNegative,
);
const FLAGS: Spec = spec(
    "flags",
    "bits",
    "1 HOT, 2 SATURATED, 4 NO_COUNTS, 8 DEAD, 16 FLAT_SATURATED, 32 NOISY, 64 UNMEASURED",
    Range::Flags,
);
const PRNU: Spec = spec(
    "prnu",
    "relative",
    "relative photon response from the flat (mean 1 over the normalising pixels)",
    Range::NonNegative,
);
const PRNU_SD: Spec = spec(
    "prnu_sd",
    "relative",
    "standard uncertainty of prnu",
    Range::NonNegative,
);
const OFFSET: Spec = spec(
    "offset_adu",
    "ADU",
    "offset: mean of the dark frames",
    Range::Finite,
);
const OFFSET_SD: Spec = spec(
    "offset_sd_adu",
    "ADU",
    "standard uncertainty of offset_adu",
    Range::NonNegative,
);
const RN: Spec = spec(
    "read_noise_adu",
    "ADU",
    "read noise: sd of the dark frames less rounding (1/12 ADU^2)",
    Range::NonNegative,
);
const RN_SD: Spec = spec(
    "read_noise_sd_adu",
    "ADU",
    "standard uncertainty of read_noise_adu",
    Range::NonNegative,
);
const GAIN: Spec = spec(
    "gain_adu_per_e",
    "ADU/e-",
    "gain, ADU per (input) electron, from the photon-transfer curve",
    Range::Positive,
);
const GAIN_SD: Spec = spec(
    "gain_sd_adu_per_e",
    "ADU/e-",
    "standard uncertainty of gain_adu_per_e",
    Range::NonNegative,
);
const RN_E: Spec = spec(
    "read_noise_e",
    "e-",
    "read noise in electrons (input-referred for an EMCCD)",
    Range::NonNegative,
);

/// Every map name this version knows (stale ones are removed on save).
const ALL_SPECS: [Spec; 12] = [
    DCR, DCR_SD, FLAGS, PRNU, PRNU_SD, OFFSET, OFFSET_SD, RN, RN_SD, GAIN, GAIN_SD, RN_E,
];

enum Data<'a> {
    F(&'a [f64]),
    U8(&'a [u8]),
}

fn map_err(name: &str, path: &Path, why: impl Into<String>) -> CalibrationError {
    CalibrationError::Map {
        name: name.to_string(),
        path: path.to_path_buf(),
        why: why.into(),
    }
}

fn check_values(
    spec: &Spec,
    values: &Data,
    width: u32,
    path: &Path,
) -> Result<(), CalibrationError> {
    let at = |i: usize| (i % width as usize, i / width as usize);
    match values {
        Data::F(v) => {
            for (i, &x) in v.iter().enumerate() {
                let ok = match spec.range {
                    Range::Finite => x.is_finite(),
                    Range::NonNegative => x.is_finite() && x >= 0.0,
                    Range::Positive => x.is_finite() && x > 0.0,
                    Range::Flags => false,
                };
                if !ok || (x as f32).is_infinite() {
                    let (px, py) = at(i);
                    let need = match spec.range {
                        Range::Finite => "finite",
                        Range::NonNegative => "finite and not negative",
                        Range::Positive => "finite and positive",
                        Range::Flags => "a flag byte",
                    };
                    return Err(map_err(
                        spec.name,
                        path,
                        format!(
                            "pixel ({px}, {py}) holds {x}; values must be {need} (and fit f32)"
                        ),
                    ));
                }
            }
        }
        Data::U8(v) => {
            if let Some(i) = v.iter().position(|&f| f & !flags::ALL != 0) {
                let (px, py) = at(i);
                return Err(map_err(
                    spec.name,
                    path,
                    format!(
                        "pixel ({px}, {py}) holds flag byte {:#04x}: bits {:#04x} are not defined in version {VERSION}",
                        v[i],
                        v[i] & !flags::ALL
                    ),
                ));
            }
        }
    }
    Ok(())
}

fn check_len(spec: &Spec, len: usize, pixels: usize) -> Result<(), CalibrationError> {
    if len != pixels {
        return Err(map_err(
            spec.name,
            Path::new("(in memory)"),
            format!("holds {len} values for {pixels} pixels"),
        ));
    }
    Ok(())
}

/// Every f64 in a serialisable value is finite (no NaN/∞ reaches a file).
fn check_finite(what: &str, v: &impl Serialize) -> Result<(), CalibrationError> {
    fn walk(v: &toml::Value, path: &str) -> Result<(), String> {
        match v {
            toml::Value::Float(x) if !x.is_finite() => Err(format!("{path} = {x}")),
            toml::Value::Array(a) => a
                .iter()
                .enumerate()
                .try_for_each(|(i, x)| walk(x, &format!("{path}[{i}]"))),
            toml::Value::Table(t) => t
                .iter()
                .try_for_each(|(k, x)| walk(x, &format!("{path}.{k}"))),
            _ => Ok(()),
        }
    }
    let value = toml::Value::try_from(v)
        .map_err(|e| CalibrationError::invalid("header", format!("{what}: {e}")))?;
    walk(&value, what)
        .map_err(|p| CalibrationError::invalid("header", format!("{p} is not finite")))
}

fn check_size(width: u32, height: u32) -> Result<usize, CalibrationError> {
    let pixels = width as u64 * height as u64;
    if width == 0 || height == 0 || pixels > 1 << 31 {
        return Err(CalibrationError::invalid(
            "width x height",
            format!("{width}x{height} is not a sensor size (1 ..= 2^31 pixels)"),
        ));
    }
    Ok(pixels as usize)
}

/// Checks a SPAD calibration's sizes, values and hot criterion.
pub fn validate_spad(c: &Calibration) -> Result<(), CalibrationError> {
    let n = check_size(c.width, c.height)?;
    let mem = Path::new("(in memory)");
    for (spec, data) in spad_maps(c) {
        let len = match data {
            Data::F(v) => v.len(),
            Data::U8(v) => v.len(),
        };
        check_len(&spec, len, n)?;
        check_values(&spec, &data, c.width, mem)?;
    }
    if c.prnu.is_some() != c.prnu_sd.is_some() || c.prnu.is_some() != c.flat.is_some() {
        return Err(CalibrationError::invalid(
            "prnu",
            "prnu, prnu_sd and the flat summary must be present together",
        ));
    }
    if !(c.tau_s.is_finite() && c.tau_s > 0.0) {
        return Err(CalibrationError::invalid("tau_s", format!("{} s", c.tau_s)));
    }
    if !(c.plane_period_s.is_finite() && c.plane_period_s > 0.0) {
        return Err(CalibrationError::invalid(
            "plane_period_s",
            format!("{} s", c.plane_period_s),
        ));
    }
    if c.planes == 0 {
        return Err(CalibrationError::invalid("planes", "must be at least 1"));
    }
    check_finite("spad.dark", &c.dark)?;
    if let Some(f) = &c.flat {
        check_finite("spad.flat", f)?;
    }
    check_finite("spad.hot_criterion", &c.hot_criterion)?;
    // The stored critical DCR must follow from the stored criterion.
    let hc = &c.hot_criterion;
    let again = HotCriterion::new(
        hc.n_window,
        hc.threshold_int,
        &hc.kernel()?,
        hc.tau_s,
        hc.background_light_hz,
        hc.neighbour_dcr_hz,
        hc.source.clone(),
    )?;
    let same = match (again.dcr_critical_hz, hc.dcr_critical_hz) {
        (None, None) => true,
        (Some(a), Some(b)) => (a - b).abs() <= 1e-9 * a.abs().max(1e-300),
        _ => false,
    };
    if !same
        || again.kernel_centre_weight != hc.kernel_centre_weight
        || again.kernel_sum != hc.kernel_sum
    {
        return Err(CalibrationError::invalid(
            "hot_criterion",
            format!(
                "the stored critical DCR {:?} Hz (centre weight {}, sum {}) does not follow from N = {}, T_int = {} and the kernel (which give {:?} Hz, {}, {}): the header was edited or corrupted",
                hc.dcr_critical_hz,
                hc.kernel_centre_weight,
                hc.kernel_sum,
                hc.n_window,
                hc.threshold_int,
                again.dcr_critical_hz,
                again.kernel_centre_weight,
                again.kernel_sum
            ),
        ));
    }
    Ok(())
}

/// Checks a frame calibration's sizes and values.
pub fn validate_frame(c: &FrameCalibration) -> Result<(), CalibrationError> {
    let n = check_size(c.width, c.height)?;
    let mem = Path::new("(in memory)");
    for (spec, data) in frame_maps(c) {
        let len = match data {
            Data::F(v) => v.len(),
            Data::U8(v) => v.len(),
        };
        check_len(&spec, len, n)?;
        check_values(&spec, &data, c.width, mem)?;
    }
    let g = c.gain_adu_per_e.is_some();
    if g != c.gain_sd_adu_per_e.is_some() || g != c.read_noise_e.is_some() {
        return Err(CalibrationError::invalid(
            "gain_adu_per_e",
            "gain, its uncertainty and the read noise in electrons must be present together",
        ));
    }
    if c.prnu.is_some() != c.prnu_sd.is_some() {
        return Err(CalibrationError::invalid(
            "prnu",
            "prnu and prnu_sd must be present together",
        ));
    }
    check_finite("frame", &c.summary)?;
    Ok(())
}

fn spad_maps(c: &Calibration) -> Vec<(Spec, Data<'_>)> {
    let mut v = vec![
        (DCR, Data::F(&c.dcr_hz)),
        (DCR_SD, Data::F(&c.dcr_sd_hz)),
        (FLAGS, Data::U8(&c.flags)),
    ];
    if let Some(p) = &c.prnu {
        v.push((PRNU, Data::F(p)));
    }
    if let Some(p) = &c.prnu_sd {
        v.push((PRNU_SD, Data::F(p)));
    }
    v
}

fn frame_maps(c: &FrameCalibration) -> Vec<(Spec, Data<'_>)> {
    let mut v = vec![
        (OFFSET, Data::F(&c.offset_adu)),
        (OFFSET_SD, Data::F(&c.offset_sd_adu)),
        (RN, Data::F(&c.read_noise_adu)),
        (RN_SD, Data::F(&c.read_noise_sd_adu)),
        (FLAGS, Data::U8(&c.flags)),
    ];
    for (spec, m) in [
        (GAIN, &c.gain_adu_per_e),
        (GAIN_SD, &c.gain_sd_adu_per_e),
        (RN_E, &c.read_noise_e),
        (PRNU, &c.prnu),
        (PRNU_SD, &c.prnu_sd),
    ] {
        if let Some(m) = m {
            v.push((spec, Data::F(m)));
        }
    }
    v
}

/// Writes one map to `path` (a file beside its final name); the entry names
/// the final file `file`.
fn write_map(
    path: &Path,
    file: String,
    spec: &Spec,
    w: u32,
    h: u32,
    data: &Data,
) -> Result<MapEntry, CalibrationError> {
    let path = path.to_path_buf();
    let out =
        std::fs::File::create(&path).map_err(|e| CalibrationError::io(&path, "creating", e))?;
    let desc = format!(
        "smartagg calibration map {} ({}): {}",
        spec.name, spec.unit, spec.description
    );
    let f32s: Vec<f32>;
    let (pixels, sample) = match data {
        Data::F(v) => {
            f32s = v.iter().map(|&x| x as f32).collect();
            (Pixels::F32(&f32s), "f32")
        }
        Data::U8(v) => (Pixels::U8(v), "u8"),
    };
    smartagg_io::image::write_described(BufWriter::new(out), w, h, pixels, &desc)
        .map_err(|e| map_err(spec.name, &path, e.why()))?;
    Ok(MapEntry {
        file,
        sample: sample.into(),
        unit: spec.unit.into(),
        description: spec.description.into(),
    })
}

fn save_dir(
    dir: &Path,
    mut header: Header,
    maps: Vec<(Spec, Data)>,
) -> Result<(), CalibrationError> {
    if dir.exists() && !dir.is_dir() {
        return Err(CalibrationError::invalid(
            "out",
            format!("{} exists and is not a directory", dir.display()),
        ));
    }
    std::fs::create_dir_all(dir).map_err(|e| CalibrationError::io(dir, "creating directory", e))?;
    // Every map is written beside its final name first: a failure there
    // leaves an earlier calibration in the directory as it was.
    let partial = |name: &str| dir.join(format!(".{name}.tif.partial"));
    let mut staged = Vec::new();
    for (spec, data) in &maps {
        let file = format!("{}.tif", spec.name);
        match write_map(
            &partial(spec.name),
            file.clone(),
            spec,
            header.width,
            header.height,
            data,
        ) {
            Ok(entry) => {
                header.maps.insert(spec.name.to_string(), entry);
                staged.push((partial(spec.name), dir.join(file)));
            }
            Err(e) => {
                for (s, _) in &maps {
                    let _ = std::fs::remove_file(partial(s.name));
                }
                return Err(e);
            }
        }
    }
    // Then the switch, in renames: the header goes out first and comes back
    // last, so a half-switched directory never reads as a calibration.
    let header_path = dir.join(HEADER_FILE);
    match std::fs::remove_file(&header_path) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => return Err(CalibrationError::io(&header_path, "removing", e)),
    }
    let written: Vec<&str> = maps.iter().map(|(s, _)| s.name).collect();
    for s in ALL_SPECS.iter().filter(|s| !written.contains(&s.name)) {
        let stale = dir.join(format!("{}.tif", s.name));
        match std::fs::remove_file(&stale) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(CalibrationError::io(&stale, "removing stale map", e)),
        }
    }
    for (from, to) in &staged {
        std::fs::rename(from, to).map_err(|e| CalibrationError::io(to, "writing", e))?;
    }
    let text = toml::to_string(&header)
        .map_err(|e| CalibrationError::invalid("header", format!("serialising: {e}")))?;
    let tmp = dir.join(format!("{HEADER_FILE}.tmp"));
    let write = || -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(b"# smartagg camera calibration, format version 1.\n# Maps are single-page TIFFs beside this file; see [maps].\n")?;
        f.write_all(text.as_bytes())?;
        f.sync_all()?;
        std::fs::rename(&tmp, &header_path)
    };
    write().map_err(|e| CalibrationError::io(&header_path, "writing", e))
}

fn base_header(kind: &str, width: u32, height: u32, provenance: &Provenance) -> Header {
    Header {
        format: FORMAT.into(),
        version: VERSION,
        kind: kind.into(),
        width,
        height,
        provenance: provenance.clone(),
        spad: None,
        frame: None,
        maps: BTreeMap::new(),
    }
}

/// Writes a SPAD calibration directory.
pub fn save_spad(c: &Calibration, dir: &Path) -> Result<(), CalibrationError> {
    validate_spad(c)?;
    let mut h = base_header("spad", c.width, c.height, &c.provenance);
    h.spad = Some(SpadHeader {
        tau_s: c.tau_s,
        plane_period_s: c.plane_period_s,
        planes: c.planes,
        dark: c.dark.clone(),
        flat: c.flat.clone(),
        hot_criterion: c.hot_criterion.clone(),
    });
    save_dir(dir, h, spad_maps(c))
}

/// Writes a frame-camera calibration directory.
pub fn save_frame(c: &FrameCalibration, dir: &Path) -> Result<(), CalibrationError> {
    validate_frame(c)?;
    let mut h = base_header(c.camera.as_str(), c.width, c.height, &c.provenance);
    h.frame = Some(c.summary.clone());
    save_dir(dir, h, frame_maps(c))
}

/// Reads the header of `path` (a directory or its header file): the
/// directory and the parsed header.
fn read_header(path: &Path) -> Result<(PathBuf, PathBuf, Header), CalibrationError> {
    let (dir, header_path) = if path.is_dir() {
        (path.to_path_buf(), path.join(HEADER_FILE))
    } else {
        let dir = path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        (dir, path.to_path_buf())
    };
    let text = match std::fs::read(&header_path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(CalibrationError::NotCalibration {
                path: path.to_path_buf(),
                why: format!("{} does not exist", header_path.display()),
            })
        }
        Err(e) => return Err(CalibrationError::io(&header_path, "reading", e)),
    };
    let text = String::from_utf8(text).map_err(|_| CalibrationError::NotCalibration {
        path: header_path.clone(),
        why: "the header is not UTF-8 text".into(),
    })?;
    let header_err = |why: String| CalibrationError::Header {
        path: header_path.clone(),
        why,
    };
    let table: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| header_err(format!("not valid TOML: {e}")))?;
    match table.get("format").and_then(|v| v.as_str()) {
        Some(FORMAT) => {}
        other => {
            return Err(CalibrationError::NotCalibration {
                path: header_path.clone(),
                why: format!("its `format` is {other:?}, not \"{FORMAT}\""),
            })
        }
    }
    let version = table
        .get("version")
        .and_then(|v| v.as_integer())
        .ok_or_else(|| header_err("`version` is missing or not an integer".into()))?;
    if version > VERSION as i64 {
        return Err(CalibrationError::UnsupportedVersion {
            path: header_path.clone(),
            found: u32::try_from(version).unwrap_or(u32::MAX),
            supported: VERSION,
        });
    }
    if version < 1 {
        return Err(header_err(format!("`version` {version} is not a version")));
    }
    let header: Header = table
        .try_into()
        .map_err(|e: toml::de::Error| header_err(e.to_string()))?;
    Ok((dir, header_path, header))
}

fn resolve(dir: &Path, name: &str, entry: Option<&MapEntry>) -> Result<PathBuf, CalibrationError> {
    let default = dir.join(format!("{name}.tif"));
    let Some(entry) = entry else {
        return Err(CalibrationError::MissingMap {
            name: name.into(),
            path: default,
        });
    };
    let rel = Path::new(&entry.file);
    if rel.components().any(|c| !matches!(c, Component::Normal(_))) {
        return Err(map_err(
            name,
            rel,
            "the file must be a plain name inside the calibration directory",
        ));
    }
    Ok(dir.join(rel))
}

fn read_map(
    dir: &Path,
    header: &Header,
    spec: &Spec,
    required: bool,
) -> Result<Option<MapValues>, CalibrationError> {
    let entry = header.maps.get(spec.name);
    if entry.is_none() && !required {
        return Ok(None);
    }
    let path = resolve(dir, spec.name, entry)?;
    let entry = entry.expect("resolved above");
    let want = if spec.range == Range::Flags {
        "u8"
    } else {
        "f32"
    };
    if entry.sample != want {
        return Err(map_err(
            spec.name,
            &path,
            format!(
                "the header says sample `{}`, version 1 stores `{want}`",
                entry.sample
            ),
        ));
    }
    let file = match std::fs::File::open(&path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(CalibrationError::MissingMap {
                name: spec.name.into(),
                path,
            })
        }
        Err(e) => return Err(CalibrationError::io(&path, "opening", e)),
    };
    let bad = |why: String| map_err(spec.name, &path, why);
    let img = smartagg_io::image::read_image(BufReader::new(file), &path.display().to_string())
        .map_err(|e| bad(e.why()))?;
    let (w, h) = (img.width, img.height);
    if (w, h) != (header.width, header.height) {
        return Err(bad(format!(
            "is {w}x{h} pixels, the calibration is {}x{}",
            header.width, header.height
        )));
    }
    let values = match (img.samples, spec.range) {
        (Samples::F32(v), r) if r != Range::Flags => {
            MapValues::F(v.into_iter().map(f64::from).collect())
        }
        (Samples::U8(v), Range::Flags) => MapValues::U8(v),
        _ => return Err(bad(format!("is not a single-channel {want} TIFF"))),
    };
    let data = match &values {
        MapValues::F(v) => Data::F(v),
        MapValues::U8(v) => Data::U8(v),
    };
    check_values(spec, &data, header.width, &path)?;
    Ok(Some(values))
}

enum MapValues {
    F(Vec<f64>),
    U8(Vec<u8>),
}

impl MapValues {
    fn f(self) -> Vec<f64> {
        match self {
            MapValues::F(v) => v,
            MapValues::U8(v) => v.into_iter().map(f64::from).collect(),
        }
    }
    fn u8(self) -> Vec<u8> {
        match self {
            MapValues::U8(v) => v,
            MapValues::F(_) => Vec::new(),
        }
    }
}

/// Reads a calibration directory (or its header file) of any kind.
pub fn load(path: &Path) -> Result<AnyCalibration, CalibrationError> {
    let (dir, header_path, header) = read_header(path)?;
    let header_err = |why: String| CalibrationError::Header {
        path: header_path.clone(),
        why,
    };
    check_size(header.width, header.height).map_err(|e| header_err(e.to_string()))?;
    let req = |spec: &Spec| -> Result<Vec<f64>, CalibrationError> {
        Ok(read_map(&dir, &header, spec, true)?
            .map(MapValues::f)
            .unwrap_or_default())
    };
    let opt = |spec: &Spec| -> Result<Option<Vec<f64>>, CalibrationError> {
        Ok(read_map(&dir, &header, spec, false)?.map(MapValues::f))
    };
    let flags_map = read_map(&dir, &header, &FLAGS, true)?
        .map(MapValues::u8)
        .unwrap_or_default();
    let revalidate = |e: CalibrationError| header_err(e.to_string());
    match header.kind.as_str() {
        "spad" => {
            let s = header.spad.clone().ok_or_else(|| {
                header_err("kind is `spad` but the [spad] table is missing".into())
            })?;
            let c = Calibration {
                width: header.width,
                height: header.height,
                tau_s: s.tau_s,
                plane_period_s: s.plane_period_s,
                planes: s.planes,
                dcr_hz: req(&DCR)?,
                dcr_sd_hz: req(&DCR_SD)?,
                flags: flags_map,
                prnu: opt(&PRNU)?,
                prnu_sd: opt(&PRNU_SD)?,
                hot_criterion: s.hot_criterion,
                dark: s.dark,
                flat: s.flat,
                provenance: header.provenance.clone(),
            };
            validate_spad(&c).map_err(revalidate)?;
            Ok(AnyCalibration::Spad(c))
        }
        "emccd" | "scmos" => {
            let camera = if header.kind == "emccd" {
                FrameCamera::Emccd
            } else {
                FrameCamera::Scmos
            };
            let summary = header.frame.clone().ok_or_else(|| {
                header_err(format!(
                    "kind is `{}` but the [frame] table is missing",
                    header.kind
                ))
            })?;
            let c = FrameCalibration {
                camera,
                width: header.width,
                height: header.height,
                offset_adu: req(&OFFSET)?,
                offset_sd_adu: req(&OFFSET_SD)?,
                read_noise_adu: req(&RN)?,
                read_noise_sd_adu: req(&RN_SD)?,
                gain_adu_per_e: opt(&GAIN)?,
                gain_sd_adu_per_e: opt(&GAIN_SD)?,
                read_noise_e: opt(&RN_E)?,
                prnu: opt(&PRNU)?,
                prnu_sd: opt(&PRNU_SD)?,
                flags: flags_map,
                summary,
                provenance: header.provenance.clone(),
            };
            validate_frame(&c).map_err(revalidate)?;
            Ok(AnyCalibration::Frame(c))
        }
        other => Err(header_err(format!(
            "unknown kind `{other}` (spad, emccd, scmos)"
        ))),
    }
}
