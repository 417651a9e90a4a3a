//! `smartagg presets`: the cameras of Table 1 and the study's scene defaults.

use smartagg_model::params::{Camera, Preset, PresetName};

/// Arguments of `smartagg presets`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Objective magnification used for the derived figures (150 or 60).
    #[arg(long, default_value_t = 150)]
    pub objective: u32,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Prints every preset.
pub fn run(args: Args) -> anyhow::Result<()> {
    let presets: Vec<Preset> = PresetName::ALL
        .into_iter()
        .map(|n| Preset::new(n, args.objective))
        .collect::<Result<_, _>>()?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&presets)?);
        return Ok(());
    }
    println!(
        "Scene defaults (paper §4.2): molecule {:.0} photons/s, background {:.0} photons/s/um^2, objective {}x NA {:.2}, emission {:.0} nm",
        presets[0].light.flux_hz,
        presets[0].light.background_per_um2_hz,
        args.objective,
        presets[0].optics.na,
        presets[0].optics.wavelength_nm
    );
    println!();
    println!(
        "{:<20} {:>9} {:>9} {:>8} {:>10} {:>12} {:>10}  description",
        "preset", "pixel nm", "sigma px", "eta", "bg Hz/px", "period", "field px"
    );
    for p in &presets {
        let period = match &p.camera {
            Camera::Spad(c) => format!("{:.0} us", c.plane_period_s * 1e6),
            Camera::Emccd(c) => format!("{:.0} ms", c.frame_period_s * 1e3),
            Camera::Scmos(c) => format!("{:.0} ms", c.frame_period_s * 1e3),
        };
        println!(
            "{:<20} {:>9.1} {:>9.3} {:>8.3} {:>10.2} {:>12} {:>10}  {}",
            p.name.as_str(),
            p.pixel_nm(),
            p.sigma_px(),
            p.camera.eta(),
            p.background_rate_hz(),
            period,
            format!("{0}x{0}", p.study_field_px),
            p.description
        );
    }
    Ok(())
}
