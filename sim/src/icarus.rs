//! A second, 4-state simulator: the XEM6310 core with its DDR2 model run
//! under Icarus Verilog (`iverilog -g2012`, `vvp`), from power-up, with
//! every memory's initial contents X.
//!
//! Verilator ([`crate::verilator`]) is 2-state: an uninitialised register
//! or a memory word never written reads as some defined value, so a design
//! that lets power-up garbage reach its packets can still agree with the
//! model by luck. Icarus keeps X (unknown) and Z: here the packet bytes the
//! host reads from pipe-out 0xA0 are written bit for bit, an X bit as `x`,
//! and a run fails if any byte has an X or Z bit, or if the bytes differ
//! from the golden model's.
//!
//! **Power-up.** What the simulation starts from, and why:
//! * *Memories: X.* The design's block and LUT RAMs (`smartagg_hdl::bram`:
//!   the FIFOs' memories, the mask, line buffers, rings) are emitted without
//!   an `initial` block, so Icarus starts them X. The DDR2 model
//!   ([`crate::ddr2`]) returns a pseudo-random word at an address never
//!   written (DDR2 after power-up, for Verilator); for this run that read
//!   is replaced by the memory word itself, which is X until written
//!   ([`x_memory_ddr2`]). The testbench initialises no memory.
//! * *Flip-flops: their configuration values.* rust-hdl writes each
//!   register (`DFF`, and `smartagg_hdl::stream::EnableRegs`) with an
//!   `initial q = 0;`: on the Spartan-6 that is the flip-flop's INIT value,
//!   loaded by the bitstream at configuration, i.e. the board's power-up,
//!   and they are kept. Everything else the design's RESET trigger (and its
//!   START) sets, as on the board. (The generated Verilog's `initial`
//!   blocks assign only registers' `q`: 1,265 of them in 731 blocks on the
//!   64×32 core, none a memory.) Measured 2026-11-27 with those blocks
//!   stripped as well: STATUS reads X after RESET (RUNNING, ENDED,
//!   OVERFLOWED, CONFIG_ERROR, FAULT, FRAMING_ERROR), because the
//!   pipeline's control state machine has no power-on reset (RESET is
//!   acted on in its Idle state, which only the flip-flops' INIT value
//!   reaches). On the Spartan-6 every flip-flop is set at configuration, so
//!   the board is not affected; an ASIC or a part without INIT values would
//!   need a power-on reset.
//! * The DDR2 model's *controller* state (its FIFOs' pointers, the
//!   calibration counter) starts as its `initial` block says: the MCB's own
//!   reset, not the design's.
//!
//! **Host.** The testbench (module `tb`, [`testbench`]) plays a command
//! file ([`commands`], read with `$readmemh`) as the Verilator harness's
//! XEM6310 host does (`crate::harness`): RESET, the hot-pixel mask through
//! pipe-in 0x81 in blocks of four words, each block when the pipe's `ready`
//! allows it, waiting for `MEM_READY`, the wire-ins, START, waiting for
//! `RUNNING`, the planes through the block-throttled replay pipe-in 0x80,
//! STOP, and reading pipe-out 0xA0 in 16-byte blocks whenever it offers one
//! (while waiting for a pipe-in's `ready`, and after STOP until `ENDED`
//! with `FIFO_BYTES` zero), with no host stalls. The end padding is
//! stripped as the harness strips it ([`crate::harness::strip_padding`]).
//!
//! Icarus resolves an `if` on an X condition to its `else` branch, so an X
//! can be hidden inside the logic; what this run proves is that none
//! reaches the packets (nor the status wire the host polls, nor the pipes'
//! `ready` and `FIFO_BYTES` that pace it: an X there stalls the host and
//! the testbench reports it), and that the bytes are still the model's.

use crate::designs::{DesignError, DesignSpec};
use crate::harness::{block_words, strip_padding, Case};
use crate::verilator::{declared_ports, Dir};
use smartagg_hdl::registers::{status, trigger, wire_in, wire_out};
use smartagg_model::config::PipelineConfig;
use smartagg_model::packetiser::encode_stream;
use smartagg_model::registers::replay_words;
use smartagg_model::registers::StreamRegisters;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Errors of an Icarus run.
#[derive(Debug, thiserror::Error)]
pub enum IcarusError {
    /// `iverilog` or `vvp` is not installed.
    #[error("{0} not found: run scripts/setup.sh (it installs the Debian package iverilog)")]
    Missing(&'static str),
    /// Generating the design.
    #[error(transparent)]
    Design(#[from] DesignError),
    /// The model refused the case.
    #[error("model: {0}")]
    Model(String),
    /// A file or a process.
    #[error("{what}: {err}")]
    Io {
        /// What was being done.
        what: String,
        /// The error.
        err: std::io::Error,
    },
    /// `iverilog` refused the Verilog.
    #[error("iverilog failed (files in {dir}):\n{log}")]
    Compile {
        /// The run's directory (kept).
        dir: PathBuf,
        /// Its messages.
        log: String,
    },
    /// The testbench stopped on an error (a timeout, FAULT, an X on a
    /// status wire, a DDR2 protocol error) or did not finish.
    #[error("simulation failed (files in {dir}): {detail}")]
    Sim {
        /// The run's directory (kept).
        dir: PathBuf,
        /// What the testbench said.
        detail: String,
    },
    /// A packet byte read from the pipe-out had an X or Z bit.
    #[error("packet byte {offset} read as `{text}`: an X (or Z) reached the packets")]
    Unknown {
        /// Offset of the byte in the stream read (padding included).
        offset: usize,
        /// Its text as `$fwrite` printed it (`%h`).
        text: String,
    },
    /// The bytes differ from the model's.
    #[error("packet bytes differ from the model's at byte {offset} ({got} bytes, model {want})")]
    Mismatch {
        /// First differing byte.
        offset: usize,
        /// Bytes of the gateware.
        got: usize,
        /// Bytes of the model.
        want: usize,
    },
}

/// What one Icarus run produced.
#[derive(Debug, Clone)]
pub struct IcarusRun {
    /// The packet bytes, end padding removed (X-free: checked).
    pub bytes: Vec<u8>,
    /// Bytes read from the pipe-out, padding included.
    pub read: usize,
    /// Clocks simulated in all (power-up to the end of the stream).
    pub clocks: u64,
    /// Clocks from START to the end of the stream.
    pub stream_clocks: u64,
    /// The final STATUS wire-out.
    pub status: u32,
    /// Wall time of `iverilog`, seconds.
    pub compile_seconds: f64,
    /// Wall time of `vvp` (the simulation), seconds.
    pub sim_seconds: f64,
}

impl IcarusRun {
    /// Simulated clocks per second of wall time (`vvp` only).
    pub fn clocks_per_second(&self) -> f64 {
        self.clocks as f64 / self.sim_seconds.max(1e-9)
    }
}

/// The read of an unwritten address in [`crate::ddr2`]'s model, and what
/// replaces it for the 4-state run.
const DDR2_GARBAGE_READ: &str = "rq[rt] = written[op_a[AW-1:0]] ? mem[op_a[AW-1:0]] : g;";
const DDR2_X_READ: &str = "rq[rt] = mem[op_a[AW-1:0]]; // 4-state: X until written";

/// The wrapper's Verilog with the DDR2 model's memory X until written
/// (instead of the pseudo-random power-up words the 2-state model returns).
/// Errors if the model's read is not found (its text changed).
pub fn x_memory_ddr2(cosim_verilog: &str) -> Result<String, DesignError> {
    if cosim_verilog.matches(DDR2_GARBAGE_READ).count() != 1 {
        return Err(DesignError::Fault(
            "the DDR2 model's read of an unwritten word was not found once".into(),
        ));
    }
    Ok(cosim_verilog.replacen(DDR2_GARBAGE_READ, DDR2_X_READ, 1))
}

/// The Verilog the 4-state run simulates: the top inside the `cosim`
/// wrapper with the DDR2 model, its memory X until written.
pub fn four_state_verilog(spec: &DesignSpec, top: &str) -> Result<String, DesignError> {
    if !spec.ddr() {
        return Err(DesignError::Unsupported {
            what: format!("{} under Icarus", spec.config.name()),
            why: "the Icarus run drives the XEM6310 core (DDR2 configurations)".into(),
        });
    }
    x_memory_ddr2(&spec.cosim_verilog(top, false)?)
}

/// Command opcodes of the testbench's script (bits 63..56 of a command;
/// bits 55..48 an argument `a`, bits 31..0 a value `v`).
mod op {
    /// End of the script: check the DDR2 model, report, finish.
    pub const END: u8 = 0x00;
    /// Wire-in `a` := `v` (held).
    pub const WIRE: u8 = 0x01;
    /// Trigger word `v` for one clock.
    pub const TRIGGER: u8 = 0x02;
    /// A block of pipe-in `a` (0: replay, 1: mask): wait for its `ready`
    /// (reading pipe-out blocks meanwhile); the next four commands are its
    /// words.
    pub const BLOCK: u8 = 0x03;
    /// A pipe word `v`, written on one clock.
    pub const DATA: u8 = 0x04;
    /// Clock (reading pipe-out blocks) until STATUS & `v` is non-zero.
    pub const WAIT: u8 = 0x05;
    /// Mark: the stream's first clock (after START).
    pub const MARK: u8 = 0x06;
    /// Clock, reading pipe-out blocks, until ENDED and FIFO_BYTES = 0.
    pub const DRAIN: u8 = 0x07;
}

fn cmd(op: u8, a: u8, v: u32) -> u64 {
    (op as u64) << 56 | (a as u64) << 48 | v as u64
}

/// The model configuration of a case on a design: the Verilator
/// harness's ([`crate::harness::model_config`]).
pub fn model_config(spec: &DesignSpec, case: &Case) -> Result<PipelineConfig, IcarusError> {
    crate::harness::model_config(spec, case).map_err(|e| IcarusError::Model(e.to_string()))
}

/// The testbench's script for a case (replay source; the case's host
/// stalls are not played: the host never stalls): the registers and mask
/// bytes the host writes ([`crate::harness::stream_registers`], the host's
/// own [`smartagg_model::registers::StreamRegisters`]), the mask only with
/// MASK_ENABLE, as the host sends it.
pub fn commands(spec: &DesignSpec, case: &Case) -> Result<Vec<u64>, IcarusError> {
    let regs = crate::harness::stream_registers(spec, case)
        .map_err(|e| IcarusError::Model(e.to_string()))?;
    let regs = StreamRegisters {
        source_replay: true,
        ..regs
    };
    let mut c = vec![cmd(op::TRIGGER, 0, 1 << trigger::RESET)];
    let blocks = |c: &mut Vec<u64>, pipe: u8, words: &[u32]| {
        for block in words.chunks(4) {
            c.push(cmd(op::BLOCK, pipe, 0));
            for k in 0..4 {
                c.push(cmd(op::DATA, 0, block.get(k).copied().unwrap_or(0)));
            }
        }
    };
    if let Some(bytes) = &regs.mask {
        blocks(&mut c, 1, &block_words(bytes));
    }
    c.push(cmd(op::WAIT, 0, status::MEM_READY));
    for (a, v) in regs.wire_ins() {
        c.push(cmd(op::WIRE, a, v));
    }
    c.push(cmd(op::TRIGGER, 0, 1 << trigger::START));
    c.push(cmd(op::MARK, 0, 0));
    c.push(cmd(op::WAIT, 0, status::RUNNING));
    blocks(&mut c, 0, &replay_words(&case.planes));
    c.push(cmd(op::TRIGGER, 0, 1 << trigger::STOP));
    c.push(cmd(op::DRAIN, 0, 0));
    c.push(cmd(op::END, 0, 0));
    Ok(c)
}

/// The testbench module `tb` for the wrapper `cosim` in `verilog`: a clock
/// the testbench steps itself (inputs change while it is low), the host
/// script of `+cmds=<file>` ([`commands`]), every pipe-out byte read
/// written to `+out=<file>` as `%h` (two hex digits, `x`/`X` for X bits),
/// and a give-up after `limit` clocks in any one wait.
pub fn testbench(verilog: &str, commands: usize, limit: u64) -> Result<String, DesignError> {
    let ports = declared_ports(verilog, "cosim").map_err(DesignError::from)?;
    let mut decl = String::new();
    let mut conns = Vec::new();
    let mut inputs = Vec::new();
    for p in &ports {
        let range = if p.width == 1 {
            String::new()
        } else {
            format!("[{}:0] ", p.width - 1)
        };
        let kind = if p.dir == Dir::In { "reg" } else { "wire" };
        let _ = writeln!(decl, "    {kind} {range}{};", p.name);
        conns.push(format!(".{0}({0})", p.name));
        if p.dir == Dir::In && p.name != "clock" {
            inputs.push(p.name.clone());
        }
    }
    let need = [
        "clock",
        "trigger",
        "replay_write",
        "replay_data",
        "replay_ready",
        "mask_write",
        "mask_data",
        "mask_ready",
        "out_read",
        "out_data",
        "out_ready",
        "sensor_empty",
        "ddr_error",
    ];
    for n in need {
        if !ports.iter().any(|p| p.name == n) {
            return Err(DesignError::Unsupported {
                what: format!("port `{n}`"),
                why: "the wrapper has no such port".into(),
            });
        }
    }
    for i in 0..wire_in::COUNT {
        if !ports.iter().any(|p| p.name == format!("wire_in_{i}")) {
            return Err(DesignError::Unsupported {
                what: format!("port `wire_in_{i}`"),
                why: "the wrapper has no such port".into(),
            });
        }
    }
    // The host's inputs at power-up: nothing driven (the sensor FIFO empty).
    let mut init = String::new();
    for n in &inputs {
        let v = if n == "sensor_empty" { "1" } else { "0" };
        let _ = writeln!(init, "        {n} = {v};");
    }
    let mut wire_case = String::new();
    for i in 0..wire_in::COUNT {
        let _ = writeln!(wire_case, "                    {i}: wire_in_{i} = v;");
    }
    // The wrapper numbers the wire-outs from STATUS, the first.
    let status = "wire_out_0".to_string();
    let fifo_bytes = format!("wire_out_{}", wire_out::FIFO_BYTES - wire_out::STATUS);
    Ok(format!(
        r#"
// 4-state testbench (smartagg-sim, icarus.rs): the host of the XEM6310 core.
`timescale 1ns/1ns
module tb;
{decl}
    cosim dut({conns});
    reg [63:0] cmds [0:{last}];
    integer pc, f, cycles, pending, start, waited, k;
    reg issued;
    reg [7:0] opc, a;
    reg [31:0] v;
    reg [1023:0] cmd_file, out_file;
    localparam LIMIT = {limit};
    localparam ST_ENDED = 32'h{ended:x}, ST_FAULT = 32'h{fault:x}, ST_CONFIG_ERROR = 32'h{cfg_err:x};

    task fail(input [8*80-1:0] what);
        begin
            $display("TB-ERROR %0s at clock %0d (status %h, fifo_bytes %h, command %0d)",
                what, cycles, {status}, {fifo_bytes}, pc);
            $fclose(f);
            $finish;
        end
    endtask

    // One clock: the word of the previous read strobe taken, the edge, the
    // strobes cleared (as the Verilator harness's `clock`).
    task step;
        begin
            if (issued) begin
                $fwrite(f, "%h\n%h\n%h\n%h\n", out_data[7:0], out_data[15:8], out_data[23:16], out_data[31:24]);
                pending = pending - 1;
            end
            issued = out_read;
            #5 clock = 1;
            #5 clock = 0;
            cycles = cycles + 1;
            trigger = 0;
            replay_write = 0;
            mask_write = 0;
            out_read = 0;
        end
    endtask

    // One 16-byte block from the pipe-out if it offers one.
    task read_block;
        begin
            if (pending == 0 && out_ready === 1'b1) begin
                for (k = 0; k < 4; k = k + 1) begin
                    out_read = 1;
                    pending = pending + 1;
                    step;
                end
                step;
            end
        end
    endtask

    task check_status;
        begin
            if (^{status} === 1'bx) fail("X on STATUS");
            if (({status} & ST_FAULT) != 0) fail("FAULT");
            if (({status} & ST_CONFIG_ERROR) != 0) fail("CONFIG_ERROR");
        end
    endtask

    initial begin
        clock = 0;
{init}        issued = 0;
        pending = 0;
        cycles = 0;
        start = 0;
        if (!$value$plusargs("cmds=%s", cmd_file)) begin $display("TB-ERROR no +cmds"); $finish; end
        if (!$value$plusargs("out=%s", out_file)) begin $display("TB-ERROR no +out"); $finish; end
        $readmemh(cmd_file, cmds);
        f = $fopen(out_file, "w");
        pc = 0;
        forever begin
            opc = cmds[pc][63:56];
            a = cmds[pc][55:48];
            v = cmds[pc][31:0];
            if (^cmds[pc] === 1'bx) fail("command file short");
            case (opc)
                8'h{end_:02x}: begin
                    if (ddr_error !== 1'b0) fail("DDR2 model protocol error");
                    $display("TB-DONE clocks %0d start %0d status %h", cycles, start, {status});
                    $fclose(f);
                    $finish;
                end
                8'h{wire:02x}: case (a)
{wire_case}                    default: fail("bad wire-in");
                endcase
                8'h{trig:02x}: begin trigger = v; step; end
                8'h{block:02x}: begin
                    waited = 0;
                    while ((a == 0 ? replay_ready : mask_ready) !== 1'b1) begin
                        read_block;
                        step;
                        waited = waited + 1;
                        if (waited > LIMIT) fail("pipe-in never ready");
                    end
                    for (k = 0; k < 4; k = k + 1) begin
                        pc = pc + 1;
                        if (cmds[pc][63:56] != 8'h{data:02x}) fail("block without its words");
                        if (a == 0) begin replay_write = 1; replay_data = cmds[pc][31:0]; end
                        else begin mask_write = 1; mask_data = cmds[pc][31:0]; end
                        step;
                    end
                end
                8'h{wait_:02x}: begin
                    waited = 0;
                    while (({status} & v) == 0) begin
                        check_status;
                        read_block;
                        step;
                        waited = waited + 1;
                        if (waited > LIMIT) fail("status bit never set");
                    end
                    check_status;
                end
                8'h{mark:02x}: start = cycles;
                8'h{drain:02x}: begin
                    waited = 0;
                    while (!(({status} & ST_ENDED) != 0 && {fifo_bytes} == 0 && pending == 0)) begin
                        check_status;
                        if (^{fifo_bytes} === 1'bx) fail("X on FIFO_BYTES");
                        read_block;
                        step;
                        waited = waited + 1;
                        if (waited > LIMIT) fail("the stream did not end");
                    end
                    check_status;
                end
                default: fail("bad command");
            endcase
            pc = pc + 1;
        end
    end
endmodule
"#,
        conns = conns.join(", "),
        last = commands.max(1) - 1,
        ended = status::ENDED,
        fault = status::FAULT,
        cfg_err = status::CONFIG_ERROR,
        end_ = op::END,
        wire = op::WIRE,
        trig = op::TRIGGER,
        block = op::BLOCK,
        data = op::DATA,
        wait_ = op::WAIT,
        mark = op::MARK,
        drain = op::DRAIN,
    ))
}

/// The bytes of the testbench's output (one `%h` byte a line): an error
/// naming the first byte with an X or Z bit.
pub fn parse_bytes(text: &str) -> Result<Vec<u8>, IcarusError> {
    let mut out = Vec::new();
    for (offset, line) in text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .enumerate()
    {
        let bad = || IcarusError::Unknown {
            offset,
            text: line.to_string(),
        };
        if line.len() != 2 || !line.chars().all(|c| c.is_ascii_hexdigit()) {
            return Err(bad());
        }
        out.push(u8::from_str_radix(line, 16).map_err(|_| bad())?);
    }
    Ok(out)
}

fn tool(name: &'static str) -> Result<(), IcarusError> {
    match Command::new(name).arg("-V").output() {
        Ok(_) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(IcarusError::Missing(name)),
        Err(err) => Err(IcarusError::Io {
            what: format!("running {name}"),
            err,
        }),
    }
}

fn io<T>(what: impl Into<String>, r: std::io::Result<T>) -> Result<T, IcarusError> {
    r.map_err(|err| IcarusError::Io {
        what: what.into(),
        err,
    })
}

/// Wall time after which `vvp` is stopped. The testbench ends every wait
/// after a limit of simulated clocks, but a zero-delay loop (two processes
/// waking each other without simulated time passing) never reaches it:
/// the run would hang. Twenty minutes is about 14 times the longest run on
/// the 2-core CI machine (86 s).
pub const VVP_WALL_LIMIT: std::time::Duration = std::time::Duration::from_secs(20 * 60);

/// Runs `cmd` with its standard output and error into the file `log`;
/// returns that text, or `None` when the command ran past `limit` (it is
/// killed).
pub fn run_with_wall_limit(
    cmd: &mut Command,
    log: &Path,
    limit: std::time::Duration,
) -> Result<Option<String>, IcarusError> {
    let program = cmd.get_program().to_string_lossy().into_owned();
    let what = || format!("running {program}");
    let out = io(
        format!("creating {}", log.display()),
        std::fs::File::create(log),
    )?;
    let err = io(what(), out.try_clone())?;
    let mut child = io(what(), cmd.stdout(out).stderr(err).spawn())?;
    let t0 = std::time::Instant::now();
    loop {
        if io(what(), child.try_wait())?.is_some() {
            break;
        }
        if t0.elapsed() > limit {
            child.kill().ok();
            child.wait().ok();
            return Ok(None);
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let text = io(format!("reading {}", log.display()), std::fs::read(log))?;
    Ok(Some(String::from_utf8_lossy(&text).into_owned()))
}

/// A fresh directory for one run: `$CARGO_TARGET_DIR/icarus/` (or the
/// workspace's `target/icarus/`), named by process and time.
fn run_dir() -> Result<PathBuf, IcarusError> {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../target"));
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let dir = target
        .join("icarus")
        .join(format!("run-{}-{nanos}", std::process::id()));
    io(
        format!("creating {}", dir.display()),
        std::fs::create_dir_all(&dir),
    )?;
    Ok(dir)
}

/// Compiles `verilog` (the `cosim` wrapper) with the testbench and plays
/// the case's script under `vvp`. The run's directory is removed when the
/// run succeeds and kept (named in the error) when it fails.
pub fn run_verilog(
    spec: &DesignSpec,
    verilog: &str,
    case: &Case,
) -> Result<IcarusRun, IcarusError> {
    tool("iverilog")?;
    tool("vvp")?;
    let cmds = commands(spec, case)?;
    let wpp = (spec.width * spec.height / crate::designs::P) as u64;
    let limit = 100_000 + (case.planes.len() as u64 + case.n as u64 + 4) * wpp * 12;
    let tb = testbench(verilog, cmds.len(), limit)?;
    let dir = run_dir()?;
    let file = |name: &str, text: &str| -> Result<PathBuf, IcarusError> {
        let p = dir.join(name);
        io(format!("writing {}", p.display()), std::fs::write(&p, text))?;
        Ok(p)
    };
    let design = file("cosim.v", verilog)?;
    let tbv = file("tb.v", &tb)?;
    let script: String = cmds.iter().map(|c| format!("{c:016x}\n")).collect();
    let cmd_file = file("commands.hex", &script)?;
    let out_file = dir.join("bytes.hex");
    let vvp = dir.join("sim.vvp");

    let t0 = std::time::Instant::now();
    let c = io(
        "running iverilog",
        Command::new("iverilog")
            .args(["-g2012", "-s", "tb", "-o"])
            .arg(&vvp)
            .arg(&design)
            .arg(&tbv)
            .output(),
    )?;
    let compile_seconds = t0.elapsed().as_secs_f64();
    if !c.status.success() {
        return Err(IcarusError::Compile {
            dir,
            log: format!(
                "{}{}",
                String::from_utf8_lossy(&c.stdout),
                String::from_utf8_lossy(&c.stderr)
            ),
        });
    }
    let t1 = std::time::Instant::now();
    let mut vvp_cmd = Command::new("vvp");
    vvp_cmd
        .arg("-n")
        .arg(&vvp)
        .arg(format!("+cmds={}", cmd_file.display()))
        .arg(format!("+out={}", out_file.display()));
    let log = run_with_wall_limit(&mut vvp_cmd, &dir.join("vvp.log"), VVP_WALL_LIMIT);
    let sim_seconds = t1.elapsed().as_secs_f64();
    let sim_err = |detail: String| IcarusError::Sim {
        dir: dir.clone(),
        detail,
    };
    let log = match log? {
        Some(log) => log,
        None => {
            return Err(sim_err(format!(
                "vvp ran past its wall-clock limit of {} s and was stopped: a \
                 zero-delay loop (processes that wake each other without \
                 simulated time passing) never reaches the testbench's clock limit",
                VVP_WALL_LIMIT.as_secs()
            )))
        }
    };
    if let Some(line) = log.lines().find(|l| l.starts_with("TB-ERROR")) {
        return Err(sim_err(line.to_string()));
    }
    let done = log
        .lines()
        .find_map(|l| l.strip_prefix("TB-DONE "))
        .ok_or_else(|| sim_err(format!("no TB-DONE in vvp's output:\n{log}")))?;
    let fields: Vec<&str> = done.split_whitespace().collect();
    let (clocks, start, status) = match fields.as_slice() {
        ["clocks", c, "start", s, "status", st] => (
            c.parse::<u64>().ok(),
            s.parse::<u64>().ok(),
            u32::from_str_radix(st, 16).ok(),
        ),
        _ => (None, None, None),
    };
    let (Some(clocks), Some(start)) = (clocks, start) else {
        return Err(sim_err(format!("unreadable `TB-DONE {done}`")));
    };
    let Some(status) = status else {
        return Err(sim_err(format!("X on STATUS at the end: `TB-DONE {done}`")));
    };
    let text = io(
        format!("reading {}", out_file.display()),
        std::fs::read_to_string(&out_file),
    )?;
    let read = parse_bytes(&text)?;
    let bytes = strip_padding(&read);
    std::fs::remove_dir_all(&dir).ok();
    Ok(IcarusRun {
        read: read.len(),
        bytes,
        clocks,
        stream_clocks: clocks - start,
        status,
        compile_seconds,
        sim_seconds,
    })
}

/// Runs the case through the design's generated core under Icarus
/// ([`four_state_verilog`], [`run_verilog`]) and compares its packet bytes
/// with the golden model's: the run, or the first difference.
pub fn check(spec: &DesignSpec, case: &Case) -> Result<IcarusRun, IcarusError> {
    let top = spec.top_verilog()?;
    check_verilog(spec, &four_state_verilog(spec, &top)?, case)
}

/// As [`check`] on given wrapper Verilog (e.g. with a fault injected).
pub fn check_verilog(
    spec: &DesignSpec,
    verilog: &str,
    case: &Case,
) -> Result<IcarusRun, IcarusError> {
    let cfg = model_config(spec, case)?;
    let records = smartagg_model::pipeline::run(cfg, case.planes.clone())
        .map_err(|e| IcarusError::Model(e.to_string()))?;
    let want = encode_stream(&records).map_err(|e| IcarusError::Model(e.to_string()))?;
    let run = run_verilog(spec, verilog, case)?;
    if run.bytes != want {
        let offset = run
            .bytes
            .iter()
            .zip(&want)
            .position(|(a, b)| a != b)
            .unwrap_or(run.bytes.len().min(want.len()));
        return Err(IcarusError::Mismatch {
            offset,
            got: run.bytes.len(),
            want: want.len(),
        });
    }
    Ok(run)
}

#[cfg(test)]
mod tests {
    use super::*;
    use smartagg_model::plane::BitPlane;

    #[test]
    fn an_x_or_z_byte_is_refused_with_its_offset() {
        assert_eq!(parse_bytes("00\nff\n3a\n").unwrap(), vec![0, 0xff, 0x3a]);
        for bad in ["x0", "0X", "xx", "z1", "Zz", "0"] {
            match parse_bytes(&format!("12\n{bad}\n")) {
                Err(IcarusError::Unknown { offset: 1, text }) => assert_eq!(text, bad),
                other => panic!("{bad}: {other:?}"),
            }
        }
    }

    /// A design whose two processes wake each other without simulated time
    /// passing is stopped at the wall-clock limit; one that finishes is read.
    #[test]
    fn a_zero_delay_loop_is_stopped_at_the_wall_clock_limit() {
        let dir = run_dir().unwrap();
        let cases = [
            (
                "loop",
                "module t; reg a = 0, b = 0;\n\
                 always @(a) begin b = 1; b = 0; end\n\
                 always @(b) begin a = 1; a = 0; end\n\
                 initial #1 a = 1;\n\
                 endmodule\n",
                None,
            ),
            (
                "done",
                "module t; initial begin #5 $display(\"T-DONE\"); $finish; end endmodule\n",
                Some("T-DONE"),
            ),
        ];
        for (name, verilog, want) in cases {
            let src = dir.join(format!("{name}.v"));
            let out = dir.join(format!("{name}.vvp"));
            std::fs::write(&src, verilog).unwrap();
            let c = Command::new("iverilog")
                .args(["-g2012", "-o"])
                .arg(&out)
                .arg(&src)
                .output()
                .unwrap();
            assert!(c.status.success(), "{}", String::from_utf8_lossy(&c.stderr));
            let log = run_with_wall_limit(
                Command::new("vvp").arg("-n").arg(&out),
                &dir.join(format!("{name}.log")),
                std::time::Duration::from_secs(2),
            )
            .unwrap();
            match want {
                None => assert!(log.is_none(), "{name}: {log:?}"),
                Some(text) => assert!(log.as_deref().unwrap_or("").contains(text), "{log:?}"),
            }
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn the_ddr2_model_reads_x_where_never_written() {
        let v = crate::ddr2::verilog(10, &crate::ddr2::Ddr2Timing::default());
        let x = x_memory_ddr2(&v).unwrap();
        assert!(!x.contains(DDR2_GARBAGE_READ) && x.contains(DDR2_X_READ));
        assert!(x_memory_ddr2(&x).is_err(), "a changed model is refused");
    }

    #[test]
    fn the_script_is_the_hosts_sequence() {
        let spec = DesignSpec::new(crate::designs::Config::Spcimager150, 64, 32).unwrap();
        let planes = vec![BitPlane::zeros(64, 32); 3];
        let plain = Case::replay(2, 1, 1, 10, planes);
        let masked = Case {
            hot: vec![(3, 4), (60, 30)],
            mask_enable: true,
            ..plain.clone()
        };
        for (case, mask_words) in [(plain, 0), (masked, 64)] {
            let c = commands(&spec, &case).unwrap();
            let ops: Vec<u8> = c.iter().map(|c| (c >> 56) as u8).collect();
            assert_eq!(c[0], cmd(op::TRIGGER, 0, 1 << trigger::RESET));
            // The mask's words (only with MASK_ENABLE) and 3·64 plane
            // words, in blocks of four.
            assert_eq!(
                ops.iter().filter(|&&o| o == op::BLOCK).count(),
                (mask_words + 192) / 4
            );
            assert_eq!(
                ops.iter().filter(|&&o| o == op::DATA).count(),
                mask_words + 192
            );
            let masked_pixels = c
                .iter()
                .find(|&&w| w >> 48 == ((op::WIRE as u64) << 8 | wire_in::MASKED_PIXELS as u64))
                .map(|w| *w as u32);
            assert_eq!(masked_pixels, Some(if mask_words > 0 { 2 } else { 0 }));
            assert_eq!(&ops[ops.len() - 3..], &[op::TRIGGER, op::DRAIN, op::END]);
        }
    }
}
