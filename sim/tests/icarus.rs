//! The 4-state run (`smartagg_sim::icarus`): the reduced 64×32 SPCImager
//! 150× XEM6310 core with its DDR2 model under Icarus Verilog, from
//! power-up with every memory X, a few hundred bit-planes of a sparse scene
//! with masked hot pixels: the packet bytes must have no X bit and equal the
//! golden model's byte for byte. Needs `iverilog` (scripts/setup.sh
//! installs it); the test fails, not skips, without it.

use smartagg_model::packet::decode_all;
use smartagg_model::record::Record;
use smartagg_sim::designs::{Config, DesignSpec, REDUCED};
use smartagg_sim::harness::{threshold_at_quantile, Case};
use smartagg_sim::icarus::{self, IcarusError};
use smartagg_sim::scene::{generate, SceneSpec};

/// Bit-planes of the case (Icarus runs some thousand clocks a second).
const PLANES: usize = 300;

fn case() -> Case {
    let (w, h) = REDUCED;
    let hot = vec![(5, 5), (40, 20), (63, 0), (0, 31)];
    let scene = SceneSpec {
        hot: hot.clone(),
        hot_rate: 0.5,
        emitters: 20,
        ..SceneSpec::sparse(w, h, PLANES)
    };
    let planes = generate(&scene, 34);
    let n = 12;
    let mut case = Case {
        hot,
        mask_enable: true,
        ..Case::replay(n, 1, 2, n + 60, planes)
    };
    let spec = DesignSpec::new(Config::Spcimager150, w, h).unwrap();
    let cfg = icarus::model_config(&spec, &case).unwrap();
    case.threshold = threshold_at_quantile(&cfg, &case.planes, 0.99);
    case
}

#[test]
fn the_core_from_power_up_with_x_memories_sends_the_models_bytes_and_no_x() {
    let spec = DesignSpec::new(Config::Spcimager150, REDUCED.0, REDUCED.1).unwrap();
    let case = case();
    let t0 = std::time::Instant::now();
    let run = match icarus::check(&spec, &case) {
        Ok(r) => r,
        Err(e @ IcarusError::Missing(_)) => panic!("{e}"),
        Err(e) => panic!("4-state run failed: {e}"),
    };
    let wall = t0.elapsed().as_secs_f64();
    let d = decode_all(&run.bytes);
    let blinks = d
        .packets
        .iter()
        .filter(|p| matches!(p.record, Record::Blink(_)))
        .count();
    println!(
        "icarus: {} planes of {}x{}, N = {}, T_int = {}: {} packet bytes ({} read), {} records ({blinks} blinks); \
         {} clocks ({} from START), iverilog {:.1} s, vvp {:.1} s ({:.0} clocks/s), test wall {:.1} s",
        case.planes.len(),
        spec.width,
        spec.height,
        case.n,
        case.threshold,
        run.bytes.len(),
        run.read,
        d.packets.len(),
        run.clocks,
        run.stream_clocks,
        run.compile_seconds,
        run.sim_seconds,
        run.clocks_per_second(),
        wall
    );
    assert!(blinks > 0, "the case must produce Blink records");
    assert!(
        matches!(d.packets.last().map(|p| &p.record), Some(Record::End(_))),
        "the stream ends with StreamEnd"
    );
}

/// The output FIFO's memory made to read the word after the one addressed:
/// a word not yet written, which a 4-state simulation holds as X.
fn read_ahead_in_output_fifo(verilog: &str) -> String {
    let start = verilog
        .find("module top$owords$mem(")
        .expect("the output FIFO's memory");
    let end = start + verilog[start..].find("endmodule").unwrap();
    let body = &verilog[start..end];
    let read = "read_data <= words[read_address];";
    assert_eq!(body.matches(read).count(), 1, "{body}");
    let body = body.replace(read, "read_data <= words[read_address + 1'b1];");
    format!("{}{body}{}", &verilog[..start], &verilog[end..])
}

/// The negative check: an uninitialised memory word that reaches the
/// packets is reported as X (not read as some value, as Verilator would).
#[test]
fn a_never_written_memory_word_reaching_the_packets_is_reported_as_x() {
    let spec = DesignSpec::new(Config::Spcimager150, REDUCED.0, REDUCED.1).unwrap();
    let mut case = case();
    case.planes.truncate(24);
    let v = icarus::four_state_verilog(&spec, &spec.top_verilog().unwrap()).unwrap();
    let t0 = std::time::Instant::now();
    let r = icarus::check_verilog(&spec, &read_ahead_in_output_fifo(&v), &case);
    println!(
        "icarus, injected read-ahead: {:.1} s: {r:?}",
        t0.elapsed().as_secs_f64()
    );
    match r {
        Err(IcarusError::Unknown { offset, text }) => {
            assert!(text.contains(['x', 'X']), "byte {offset}: {text}");
        }
        other => panic!("expected an X in the packet bytes, got {other:?}"),
    }
}
