use smartagg_study::*;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let study = StudyName::parse(&args[1]).unwrap();
    let mut o = StudyOptions::default();
    let mut out = format!("/tmp/study-{}", study);
    for a in &args[2..] {
        let (k, v) = a.split_once('=').unwrap();
        match k {
            "n" => o.blinks_per_point = v.parse().unwrap(),
            "quick" => o.quick = v == "1",
            "l_min" => o.l_min = Some(v.parse().unwrap()),
            "r_assoc" => o.r_assoc = Some(v.parse().unwrap()),
            "thr" => o.frame_threshold = v.parse().unwrap(),
            "points" => o.points = Some(v.split(',').map(|x| x.parse().unwrap()).collect()),
            "out" => out = v.to_string(),
            "seed" => o.seed = v.parse().unwrap(),
            "fixed_sigma" => o.fit_sigma = v != "1",
            _ => panic!("{k}"),
        }
    }
    let plan = Plan::new(study, o).unwrap();
    let t = std::time::Instant::now();
    let out = std::path::PathBuf::from(out);
    let w = run::run_to_dir(&plan, Shard::ALL, &out, &|d, t| eprint!("\r{d}/{t}")).unwrap();
    eprintln!("\nwall {:.1}s {:?}", t.elapsed().as_secs_f64(), w.warnings);
}
