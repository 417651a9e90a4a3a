use smartagg_model::params::PresetName;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let obj: u32 = a.get(1).map_or(150, |s| s.parse().unwrap());
    let k: u32 = a.get(2).map_or(20, |s| s.parse().unwrap());
    let quick = a.get(3).is_none_or(|s| s == "quick");
    let p = if a.get(4).is_some_and(|s| s == "proj") {
        PresetName::SpcimagerProjected
    } else {
        PresetName::Spcimager
    };
    let r =
        smartagg_study::experiment::field_detection::compute_camera(p, obj, 7, quick, k).unwrap();
    println!(
        "{}",
        smartagg_study::experiment::field_detection::summary_camera(&r)
    );
}
