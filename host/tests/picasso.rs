//! `localize --out x.hdf5` writes what Picasso reads: read back with h5py
//! and PyYAML (Picasso's own readers), checked column by column against the
//! ThunderSTORM CSV of the same input, and against what Picasso's
//! `io.load_locs` needs (`/locs`, its dtype, the sidecar's `Width`,
//! `Height`, `Frames`, `Pixelsize`, the sanity filter it applies). `render`
//! draws the HDF5 table as it draws the CSV.
//!
//! python3 with h5py and yaml is required (`scripts/setup.sh` installs
//! python3-h5py and python3-yaml): without them this test fails, it does
//! not skip.

use std::path::Path;
use std::process::Command;

mod common;
use common::*;

/// Reads the HDF5 table and its sidecar as Picasso does and compares them
/// with the CSV. Prints "rows N kept M" on success.
const CHECK: &str = r#"
import csv, sys
import h5py, numpy as np, yaml

h5_path, csv_path, yaml_path, px = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
with h5py.File(h5_path, "r") as f:
    assert list(f.keys()) == ["locs"], list(f.keys())
    locs = f["locs"][...]
# Picasso <= 0.8 (io.load_locs): a record array with fields as attributes.
locs = np.rec.array(locs, dtype=locs.dtype)
want = [("frame", "u", 4), ("x", "f", 4), ("y", "f", 4), ("photons", "f", 4),
        ("sx", "f", 4), ("sy", "f", 4), ("bg", "f", 4), ("lpx", "f", 4),
        ("lpy", "f", 4), ("ellipticity", "f", 4), ("fit_status", "u", 4),
        ("n", "u", 4), ("blink", "u", 4), ("planes", "u", 4), ("flags", "u", 4),
        ("t_start", "i", 8), ("t_end", "i", 8)]
got = [(n, locs.dtype[n].kind, locs.dtype[n].itemsize) for n in locs.dtype.names]
assert got == want, got
assert locs.dtype.byteorder in "=<|", locs.dtype.byteorder

with open(csv_path, newline="") as fh:
    rows = list(csv.DictReader(fh))
assert len(rows) == len(locs), (len(rows), len(locs))
assert len(rows) > 3, len(rows)

def close(a, b, tol):
    assert abs(float(a) - float(b)) <= tol + 2e-7 * abs(float(b)), (a, b, tol)

for r, l in zip(rows, locs):
    # The CSV rounds nm to 3 decimals and photons to 2.
    close(l.x, float(r["x [nm]"]) / px, 6e-4 / px)
    close(l.y, float(r["y [nm]"]) / px, 6e-4 / px)
    close(l.sx, float(r["sigma [nm]"]) / px, 6e-4 / px)
    assert l.sx == l.sy and l.ellipticity == 0
    close(l.photons, r["intensity [photon]"], 6e-3)
    close(l.bg, r["offset [photon]"], 6e-4)
    close(l.lpx, float(r["uncertainty [nm]"]) / px, 6e-4 / px)
    assert l.lpx == l.lpy
    assert l.fit_status == int(r["fit_status"]) and l.n == 1
    assert l.blink == int(r["frame"])
    assert l.t_start == int(r["t_start [plane]"]) and l.t_end == int(r["t_end [plane]"])
    # (`flags` by name: a numpy record's .flags is its memory layout.)
    assert l.planes == int(r["planes"]) and l["flags"] == int(r["flags"])
    assert l.frame == max(l.t_start, 0)

with open(yaml_path) as fh:
    info = list(yaml.load_all(fh, Loader=yaml.SafeLoader))
assert isinstance(info, list) and len(info) >= 2 and all(isinstance(d, dict) for d in info), info
for k in ("Byte Order", "Data Type", "File", "Frames", "Height", "Width"):
    assert k in info[0], (k, info[0])
assert info[0]["Byte Order"] == "<"

def get(key):
    # picasso.lib.get_from_metadata: the last document with a truthy value.
    for d in info[::-1]:
        if d.get(key):
            return d[key]
    raise KeyError(key)

assert (get("Width"), get("Height")) == (48, 40), (get("Width"), get("Height"))
assert abs(get("Pixelsize") - px) < 1e-9, get("Pixelsize")
assert get("Frames") >= int(locs.frame.max()) + 1, (get("Frames"), locs.frame.max())

# picasso.lib.ensure_sanity, which io.load_locs applies: every good fit passes.
ok = np.all([np.isfinite(locs[n]) for n in locs.dtype.names], axis=0)
ok &= (locs.x < get("Width")) & (locs.y < get("Height"))
for n in ("x", "y", "lpx", "lpy", "photons", "ellipticity", "sx", "sy"):
    ok &= locs[n] >= 0
good = locs.fit_status == 0
assert good.sum() > 3 and np.all(ok[good]), (good.sum(), ok[good].sum())
print("rows", len(locs), "kept", int(ok.sum()))
"#;

#[test]
fn hdf5_table_reads_back_in_picasso_and_renders_as_the_csv() {
    let dir = tempfile::tempdir().unwrap();
    let rec = p(dir.path(), "rulers.spad");
    ok(&[
        "simulate",
        "--preset",
        "spcimager",
        "--scene",
        "nanoruler",
        "--field",
        "48x40",
        "--planes",
        "3000",
        "--mean-off-s",
        "0.3",
        "--seed",
        "3",
        "--out",
        &rec,
    ]);
    let rois = p(dir.path(), "blinks.rois");
    ok(&["aggregate", &rec, "--out", &rois, "--quiet"]);
    let csv = p(dir.path(), "locs.csv");
    let h5 = p(dir.path(), "locs.hdf5");
    let yaml = p(dir.path(), "locs.yaml");
    ok(&["localize", &rois, "--out", &csv, "--pixel-nm", "100"]);
    let said = ok(&["localize", &rois, "--out", &h5, "--pixel-nm", "100"]);
    assert!(said.contains("locs.yaml"), "{said}");

    // apt's python3-h5py and python3-yaml belong to the system interpreter,
    // which a pyenv or virtualenv python3 earlier on PATH would not see.
    let python = if Path::new("/usr/bin/python3").exists() {
        "/usr/bin/python3"
    } else {
        "python3"
    };
    let py = Command::new(python)
        .args(["-c", CHECK, &h5, &csv, &yaml, "100"])
        .output()
        .expect("python3 runs (scripts/setup.sh installs it)");
    assert!(
        py.status.success(),
        "the h5py/yaml check failed:\n{}\n{}",
        String::from_utf8_lossy(&py.stdout),
        String::from_utf8_lossy(&py.stderr)
    );
    assert!(String::from_utf8_lossy(&py.stdout).starts_with("rows "));

    // render draws the HDF5 table as it draws the CSV (to float precision).
    let from_csv = p(dir.path(), "csv.tif");
    let from_h5 = p(dir.path(), "h5.tif");
    ok(&["render", &csv, "--out", &from_csv]);
    ok(&["render", &h5, "--out", &from_h5]);
    let read = |path: &str| {
        smartagg_io::stack::open_stack(Path::new(path))
            .unwrap()
            .next()
            .unwrap()
            .unwrap()
    };
    let (a, b) = (read(&from_csv), read(&from_h5));
    assert_eq!((a.width, a.height), (b.width, b.height));
    let peak = a.data.iter().cloned().fold(0.0, f64::max);
    let worst = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    assert!(
        peak > 0.01 && worst <= 1e-3 * peak,
        "peak {peak}, worst {worst}"
    );

    // Without its sidecar the pixel size must be given.
    let bare = p(dir.path(), "bare.h5");
    std::fs::copy(&h5, &bare).unwrap();
    let png = p(dir.path(), "bare.png");
    let e = err(&["render", &bare, "--out", &png]);
    assert!(e.contains("--camera-pixel-nm"), "{e}");
    ok(&["render", &bare, "--out", &png, "--camera-pixel-nm", "100"]);
    // A CSV is in nm: the option is refused there.
    let e = err(&["render", &csv, "--out", &png, "--camera-pixel-nm", "100"]);
    assert!(e.contains("HDF5"), "{e}");

    // An unknown extension is refused before anything is written, and the
    // sidecar may not be the input.
    let txt = p(dir.path(), "locs.txt");
    let e = err(&["localize", &rois, "--out", &txt, "--pixel-nm", "100"]);
    assert!(e.contains(".hdf5") && e.contains(".csv"), "{e}");
    assert!(!Path::new(&txt).exists());
    let blinks_yaml = p(dir.path(), "blinks.yaml");
    std::fs::hard_link(&rois, &blinks_yaml).unwrap();
    let before = std::fs::read(&rois).unwrap();
    let e = err(&[
        "localize",
        &rois,
        "--out",
        &p(dir.path(), "blinks.h5"),
        "--pixel-nm",
        "100",
    ]);
    assert!(e.contains("destroy the input"), "{e}");
    assert_eq!(std::fs::read(&rois).unwrap(), before);
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(!names.iter().any(|n| n.ends_with(".partial")), "{names:?}");
    assert!(!names.iter().any(|n| n == "blinks.h5"), "{names:?}");
}
