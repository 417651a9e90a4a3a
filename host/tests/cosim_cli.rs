//! `smartagg cosim` on any field of a shipped configuration's sensor: the
//! design is generated and verilated for the field on demand (a field no
//! test or catalogue had), and a field outside the sensor is refused with
//! the limits named, before anything is built.

mod common;
use common::*;

#[test]
fn a_field_outside_the_sensor_is_refused_naming_the_limits() {
    for (preset, w, h) in [
        ("spcimager", "336", "240"),
        ("spcimager", "100", "72"),
        ("spcimager-projected", "64", "300"),
    ] {
        let e = err(&[
            "cosim", "--preset", preset, "--width", w, "--height", h, "--planes", "10",
        ]);
        assert!(
            e.contains(&format!("on {w}x{h}"))
                && e.contains("sized for the sensor's 320x240")
                && e.contains("multiple of 16 from 32 to 320")
                && e.contains("height from 10 to 240"),
            "{preset} {w}x{h}: {e}"
        );
        assert!(!e.contains("verilating"), "refused before building: {e}");
    }
    let e = err(&["cosim", "--objective", "100"]);
    assert!(e.contains("150x and 60x"), "{e}");
}

#[test]
fn a_field_generated_on_demand_matches_the_model() {
    let out = ok(&[
        "cosim",
        "--preset",
        "spcimager",
        "--width",
        "96",
        "--height",
        "72",
        "--planes",
        "300",
        "--seed",
        "3",
    ]);
    println!("{out}");
    assert!(
        out.starts_with("match: ") && out.contains("over 300 bit-planes"),
        "{out}"
    );
    assert!(out.contains("432 words of P = 16 pixels"), "{out}");
    let blinks: u64 = out
        .split("confirmed blinks ")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .expect("the coverage line");
    assert!(blinks > 0, "{out}");
}
