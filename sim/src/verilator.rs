//! A thin binding of Verilator: Verilog text in, a loaded shared library out.
//!
//! [`Build::get`] writes the Verilog to a cache directory keyed by a hash of
//! the text and the build options (`target/verilator-cache/<hash>/`, or
//! `$SMARTAGG_VERILATOR_CACHE/<hash>/`), runs `verilator --cc --exe --build`
//! on it together with a C++ shim generated from the top module's port list,
//! links the lot into `libcosim.so` and loads it with `libloading`. The
//! same text with the same options is verilated once: later calls (in this
//! process or the next) load the cached library.
//!
//! The shim is generic over the top's ports: port `i` of the parsed
//! [`Port`] table is set and read as little-endian 32-bit words
//! (`sa_set(h, i, words)`, `sa_get(h, i, words)`), whatever its width.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex, OnceLock};

/// Errors of building or loading a Verilated model.
#[derive(Debug, thiserror::Error)]
pub enum VerilatorError {
    /// A tool could not be started.
    #[error("cannot run `{tool}` (is it installed?): {source}")]
    Spawn {
        /// The tool.
        tool: String,
        /// Why.
        source: std::io::Error,
    },
    /// A tool ran and failed.
    #[error("`{tool}` failed in {dir}:\n{log}")]
    Failed {
        /// The tool.
        tool: String,
        /// Its working directory.
        dir: PathBuf,
        /// The tail of its output.
        log: String,
    },
    /// The cache directory could not be written.
    #[error("cache directory {path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The Verilog has no module of that name, or a port the shim cannot handle.
    #[error("Verilog: {0}")]
    Verilog(String),
    /// The shared library could not be loaded.
    #[error("loading {path}: {source}")]
    Load {
        /// The library.
        path: PathBuf,
        /// Why.
        source: libloading::Error,
    },
    /// No port of that name.
    #[error("the Verilated top has no port `{0}`")]
    NoPort(String),
}

/// Direction of a top-level port.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dir {
    /// Driven from Rust.
    In,
    /// Read from Rust.
    Out,
}

/// One top-level port of the Verilated module.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Port {
    /// Its Verilog name (also the C++ member name: letters, digits, `_`).
    pub name: String,
    /// Its direction.
    pub dir: Dir,
    /// Bits.
    pub width: usize,
}

impl Port {
    /// 32-bit words the port occupies.
    pub fn words(&self) -> usize {
        self.width.div_ceil(32)
    }
}

/// `line` without its `/* … */` comments (hdl's scheduling hints follow
/// some declarations).
fn without_block_comments(line: &str) -> String {
    let mut out = String::with_capacity(line.len());
    let mut rest = line;
    while let Some(open) = rest.find("/*") {
        out.push_str(&rest[..open]);
        match rest[open + 2..].find("*/") {
            Some(close) => rest = &rest[open + 2 + close + 2..],
            None => return out,
        }
    }
    out.push_str(rest);
    out
}

/// The port table of module `module` in `verilog` (non-ANSI declarations,
/// `input wire [a:0] name;` as rust-hdl writes them and as the co-simulation
/// wrappers are written), in declaration order, for the shim: names of
/// letters, digits and `_` only.
pub fn parse_ports(verilog: &str, module: &str) -> Result<Vec<Port>, VerilatorError> {
    let ports = declared_ports(verilog, module)?;
    if let Some(p) = ports.iter().find(|p| {
        p.name.is_empty()
            || !p
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_')
    }) {
        return Err(VerilatorError::Verilog(format!(
            "port `{}` of `{module}`: the shim needs names of letters, digits and `_`",
            p.name
        )));
    }
    Ok(ports)
}

/// The ports of module `module` in `verilog` as declared, whatever their
/// names (rust-hdl's vector elements are `name$i`), in declaration order.
pub fn declared_ports(verilog: &str, module: &str) -> Result<Vec<Port>, VerilatorError> {
    let head = format!("module {module}(");
    let start = verilog
        .find(&head)
        .ok_or_else(|| VerilatorError::Verilog(format!("no `module {module}`")))?;
    let body = &verilog[start..];
    let end = body.find("endmodule").unwrap_or(body.len());
    let mut ports = Vec::new();
    for line in body[..end].lines() {
        let line = without_block_comments(line);
        let t = line.trim();
        let (dir, rest) = if let Some(r) = t.strip_prefix("input ") {
            (Dir::In, r)
        } else if let Some(r) = t.strip_prefix("output ") {
            (Dir::Out, r)
        } else {
            continue;
        };
        let rest = rest.trim_end_matches(';').trim();
        let rest = rest
            .strip_prefix("wire")
            .or_else(|| rest.strip_prefix("reg"))
            .unwrap_or(rest)
            .trim();
        let (width, name) = if let Some(r) = rest.strip_prefix('[') {
            let (range, name) = r
                .split_once(']')
                .ok_or_else(|| VerilatorError::Verilog(format!("bad range in `{t}`")))?;
            let (hi, lo) = range
                .split_once(':')
                .ok_or_else(|| VerilatorError::Verilog(format!("bad range in `{t}`")))?;
            let hi: usize = hi
                .trim()
                .parse()
                .map_err(|_| VerilatorError::Verilog(format!("bad range in `{t}`")))?;
            let lo: usize = lo
                .trim()
                .parse()
                .map_err(|_| VerilatorError::Verilog(format!("bad range in `{t}`")))?;
            (hi + 1 - lo, name.trim())
        } else {
            (1, rest)
        };
        ports.push(Port {
            name: name.to_string(),
            dir,
            width,
        });
    }
    if ports.is_empty() {
        return Err(VerilatorError::Verilog(format!("`{module}` has no ports")));
    }
    Ok(ports)
}

/// Options of a Verilator build (part of the cache key).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct BuildOptions {
    /// Compile VCD tracing in (`--trace`).
    pub trace: bool,
    /// The top module's name.
    pub top: String,
    /// The clock port (toggled by `sa_tick`).
    pub clock: String,
    /// Profile-guided: compile an instrumented model first, run the
    /// caller's training on it ([`Build::get_trained`]), and compile the
    /// model kept with g++'s `-fprofile-use` (see the crate docs' speed
    /// section for what it gains).
    pub profile: bool,
}

/// A training run for a profile-guided build: drives the instrumented
/// model (a [`Build`] of its own, not cached) the way it will be used.
pub type Training<'a> = &'a (dyn Fn(Arc<Build>) -> Result<(), String> + 'a);

/// Bumped whenever the shim or the flags change, so old caches are not reused.
const SHIM_VERSION: u32 = 10;

fn cache_root() -> PathBuf {
    if let Some(p) = std::env::var_os("SMARTAGG_VERILATOR_CACHE") {
        return PathBuf::from(p);
    }
    // CARGO_TARGET_DIR if set, else the workspace's target/ (two levels up from sim/).
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../target"));
    target.join("verilator-cache")
}

/// A 64-bit hash of the text (CRC-64), hex: the cache key.
pub fn text_hash(text: &str) -> String {
    let crc = crc::Crc::<u64>::new(&crc::CRC_64_ECMA_182);
    format!("{:016x}", crc.checksum(text.as_bytes()))
}

fn shim_source(ports: &[Port], opts: &BuildOptions) -> String {
    let cls = format!("V{}", opts.top);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "// Generated by smartagg-sim: a C ABI over the ports of {cls}.\n\
         #include \"{cls}.h\"\n#include \"verilated.h\"\n#include <cstdint>\n#include <cstring>"
    );
    if opts.trace {
        s.push_str("#include \"verilated_vcd_c.h\"\n");
    }
    s.push_str(
        "struct SaHandle { VerilatedContext* ctx; MODEL* m; void* tr; uint64_t time; bool dirty; };\n\
         // Read by the patched ico trigger (see `patch_ico`): whether the\n\
         // inputs changed since the last eval of the model being evaluated.\n\
         thread_local bool sa_ico_pending = true;\n\
         static inline void sa_ev(SaHandle* h) { sa_ico_pending = h->dirty; h->m->eval(); h->dirty = false; }\n"
            .replace("MODEL", &cls)
            .as_str(),
    );
    // Weak: defined (by libgcov) only in the instrumented build; the code is
    // the same in both builds, as `-fprofile-use` requires.
    s.push_str("extern \"C\" void __gcov_dump(void) __attribute__((weak));\n");
    s.push_str("extern \"C\" {\n");
    // Writes the instrumented build's counts now (the library may stay
    // loaded to the process's end: Verilator's runtime makes it unloadable).
    s.push_str("void sa_profile_dump() { if (__gcov_dump) __gcov_dump(); }\n");
    let _ = writeln!(
        s,
        "void* sa_new() {{ SaHandle* h = new SaHandle; h->ctx = new VerilatedContext; \
         h->ctx->traceEverOn({trace}); h->m = new {cls}(h->ctx, \"TOP\"); h->tr = nullptr; \
         h->time = 0; h->dirty = true; return h; }}",
        trace = opts.trace
    );
    if opts.trace {
        s.push_str(
            "static void sa_dump(SaHandle* h) { if (h->tr) ((VerilatedVcdC*)h->tr)->dump(h->time); h->time++; }\n\
             int sa_trace_open(void* p, const char* path) { SaHandle* h = (SaHandle*)p; \
             if (h->tr) return 0; VerilatedVcdC* t = new VerilatedVcdC; h->m->trace(t, 99); \
             t->open(path); h->tr = t; return 1; }\n\
             void sa_trace_close(void* p) { SaHandle* h = (SaHandle*)p; \
             if (h->tr) { ((VerilatedVcdC*)h->tr)->close(); delete (VerilatedVcdC*)h->tr; h->tr = nullptr; } }\n",
        );
    } else {
        s.push_str(
            "static void sa_dump(SaHandle* h) { h->time++; }\n\
             int sa_trace_open(void*, const char*) { return 0; }\n\
             void sa_trace_close(void*) {}\n",
        );
    }
    s.push_str(
        "void sa_delete(void* p) { SaHandle* h = (SaHandle*)p; sa_trace_close(p); \
         h->m->final(); delete h->m; delete h->ctx; delete h; }\n\
         void sa_eval(void* p) { sa_ev((SaHandle*)p); }\n",
    );
    // Two evaluations per clock: the falling edge doubles as the settling
    // of the inputs set for the next rising edge.
    let _ = writeln!(
        s,
        "void sa_low(void* p) {{ SaHandle* h = (SaHandle*)p; h->m->{c} = 0; sa_ev(h); }}\n\
         void sa_tick(void* p, uint64_t n) {{ SaHandle* h = (SaHandle*)p; \
         for (uint64_t i = 0; i < n; i++) {{ if (i > 0) {{ h->m->{c} = 0; sa_ev(h); }} \
         sa_dump(h); h->m->{c} = 1; sa_ev(h); sa_dump(h); }} }}",
        c = opts.clock
    );
    // Setters and getters by port index.
    s.push_str("void sa_set(void* p, int i, const uint32_t* w) { ((SaHandle*)p)->dirty = true; auto m = ((SaHandle*)p)->m; switch (i) {\n");
    for (i, p) in ports.iter().enumerate() {
        if p.dir != Dir::In {
            continue;
        }
        let n = &p.name;
        let body = if p.width <= 32 {
            format!("m->{n} = w[0];")
        } else if p.width <= 64 {
            format!("m->{n} = ((uint64_t)w[1] << 32) | w[0];")
        } else {
            format!("for (int k = 0; k < {}; k++) m->{n}[k] = w[k];", p.words())
        };
        let _ = writeln!(s, "case {i}: {body} break;");
    }
    s.push_str("default: break; } }\n");
    s.push_str(
        "void sa_get(void* p, int i, uint32_t* w) { auto m = ((SaHandle*)p)->m; switch (i) {\n",
    );
    for (i, p) in ports.iter().enumerate() {
        let n = &p.name;
        let body = if p.width <= 32 {
            format!("w[0] = m->{n};")
        } else if p.width <= 64 {
            format!("w[0] = (uint32_t)m->{n}; w[1] = (uint32_t)(m->{n} >> 32);")
        } else {
            format!("for (int k = 0; k < {}; k++) w[k] = m->{n}[k];", p.words())
        };
        let _ = writeln!(s, "case {i}: {body} break;");
    }
    s.push_str("default: break; } }\n}\n");
    s
}

fn run(cmd: &mut Command, dir: &Path, tool: &str) -> Result<(), VerilatorError> {
    let out = cmd
        .current_dir(dir)
        .output()
        .map_err(|source| VerilatorError::Spawn {
            tool: tool.into(),
            source,
        })?;
    if out.status.success() {
        return Ok(());
    }
    let mut log = String::from_utf8_lossy(&out.stdout).into_owned();
    log.push_str(&String::from_utf8_lossy(&out.stderr));
    let tail: String = log
        .lines()
        .rev()
        .take(40)
        .collect::<Vec<_>>()
        .into_iter()
        .rev()
        .collect::<Vec<_>>()
        .join("\n");
    Err(VerilatorError::Failed {
        tool: tool.into(),
        dir: dir.to_path_buf(),
        log: tail,
    })
}

type FnNew = unsafe extern "C" fn() -> *mut std::ffi::c_void;
type FnPtr = unsafe extern "C" fn(*mut std::ffi::c_void);
type FnVoid = unsafe extern "C" fn();
type FnTick = unsafe extern "C" fn(*mut std::ffi::c_void, u64);
type FnSet = unsafe extern "C" fn(*mut std::ffi::c_void, i32, *const u32);
type FnGet = unsafe extern "C" fn(*mut std::ffi::c_void, i32, *mut u32);
type FnTraceOpen = unsafe extern "C" fn(*mut std::ffi::c_void, *const std::ffi::c_char) -> i32;

/// A Verilated design, built (or found in the cache) and loaded.
pub struct Build {
    lib: libloading::Library,
    /// The top's ports, in the order the shim numbers them.
    pub ports: Vec<Port>,
    /// The cache directory of this build.
    pub dir: PathBuf,
    /// Whether it was verilated now (false: found in the cache).
    pub fresh: bool,
    /// The options it was built with.
    pub options: BuildOptions,
    /// The input-combinational region is skipped on clock-only evaluations
    /// (see the module docs).
    pub ico_patched: bool,
    /// Compiled with the profile of a training run (see
    /// [`BuildOptions::profile`]).
    pub profiled: bool,
    /// Why a profile-guided build was compiled without a profile: its
    /// training run failed (the model is the same, only slower).
    pub training_error: Option<String>,
}

impl std::fmt::Debug for Build {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Build")
            .field("dir", &self.dir)
            .field("ports", &self.ports.len())
            .field("fresh", &self.fresh)
            .field("ico_patched", &self.ico_patched)
            .field("profiled", &self.profiled)
            .finish()
    }
}

/// One slot per cache key: filled by the first thread that builds it.
type BuildSlot = Arc<Mutex<Option<Arc<Build>>>>;

fn builds() -> &'static Mutex<HashMap<String, BuildSlot>> {
    static B: OnceLock<Mutex<HashMap<String, BuildSlot>>> = OnceLock::new();
    B.get_or_init(Default::default)
}

impl Build {
    /// The Verilated model of `verilog` (top module `opts.top`), from this
    /// process's builds, the disk cache, or verilated now.
    pub fn get(verilog: &str, opts: &BuildOptions) -> Result<Arc<Build>, VerilatorError> {
        Self::get_trained(verilog, opts, None)
    }

    /// As [`Build::get`]; a profile-guided build ([`BuildOptions::profile`])
    /// that is not cached yet runs `train` on its instrumented model first
    /// (without a training it is compiled as a plain build).
    pub fn get_trained(
        verilog: &str,
        opts: &BuildOptions,
        train: Option<Training>,
    ) -> Result<Arc<Build>, VerilatorError> {
        let key = text_hash(&format!(
            "{SHIM_VERSION}\n{opts:?}\n{}\n{verilog}",
            verilator_version()
        ));
        // One build per key in this process, even with tests in parallel threads.
        let slot = builds()
            .lock()
            .expect("build table")
            .entry(key.clone())
            .or_default()
            .clone();
        let mut slot = slot.lock().expect("build slot");
        if let Some(b) = slot.as_ref() {
            return Ok(b.clone());
        }
        let b = Arc::new(Self::verilate(verilog, opts, &key, train)?);
        *slot = Some(b.clone());
        Ok(b)
    }

    fn verilate(
        verilog: &str,
        opts: &BuildOptions,
        key: &str,
        train: Option<Training>,
    ) -> Result<Build, VerilatorError> {
        let ports = parse_ports(verilog, &opts.top)?;
        if !ports
            .iter()
            .any(|p| p.name == opts.clock && p.dir == Dir::In)
        {
            return Err(VerilatorError::NoPort(opts.clock.clone()));
        }
        let root = cache_root();
        let dir = root.join(key);
        let lib_path = dir.join("libcosim.so");
        let mut fresh = false;
        if !lib_path.exists() {
            fresh = true;
            let io = |path: &Path| {
                let path = path.to_path_buf();
                move |source| VerilatorError::Io { path, source }
            };
            let tmp = root.join(format!("{key}.tmp-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&tmp);
            std::fs::create_dir_all(&tmp).map_err(io(&tmp))?;
            std::fs::write(tmp.join("cosim.v"), verilog).map_err(io(&tmp))?;
            std::fs::write(tmp.join("shim.cpp"), shim_source(&ports, opts)).map_err(io(&tmp))?;
            let mut cmd = Command::new("verilator");
            cmd.args([
                "--cc",
                "--exe",
                "-O3",
                "--x-assign",
                "fast",
                "--x-initial",
                "fast",
                "--noassert",
                "-Wno-fatal",
                "-Wno-lint",
                "-Wno-style",
                "--top-module",
                &opts.top,
                "--Mdir",
                "obj",
                "-CFLAGS",
                "-fPIC",
                "-LDFLAGS",
                "-shared",
                "-o",
                "../libcosim.so",
            ]);
            if opts.trace {
                cmd.arg("--trace");
            }
            cmd.args(["cosim.v", "shim.cpp"]);
            run(&mut cmd, &tmp, "verilator")?;
            let ico_patched = patch_ico(&tmp.join("obj"), &opts.clock)?;
            if ico_patched {
                std::fs::write(tmp.join(ICO_MARK), "").map_err(io(&tmp))?;
            }
            let mut opt_fast = String::from(OPT_FAST);
            if let (true, Some(train)) = (opts.profile, train) {
                match Self::train(&tmp, &ports, opts, ico_patched, train)? {
                    Ok(()) => {
                        opt_fast
                            .push_str(" -fprofile-use -fprofile-correction -Wno-missing-profile");
                        std::fs::write(tmp.join(PROFILE_MARK), "").map_err(io(&tmp))?;
                    }
                    Err(why) => {
                        std::fs::write(tmp.join(TRAINING_ERROR), why).map_err(io(&tmp))?;
                    }
                }
            }
            make(&tmp, &opts.top, &opt_fast, None)?;
            // Keep the Verilog, the shim and the library; the objects are large.
            let _ = std::fs::remove_dir_all(tmp.join("obj"));
            match std::fs::rename(&tmp, &dir) {
                Ok(()) => {}
                // Another process finished the same build first: use its copy.
                Err(_) if lib_path.exists() => {
                    let _ = std::fs::remove_dir_all(&tmp);
                }
                Err(e) => return Err(io(&dir)(e)),
            }
        }
        let lib = load_library(&lib_path)?;
        Ok(Build {
            lib,
            ports,
            fresh,
            options: opts.clone(),
            ico_patched: dir.join(ICO_MARK).exists(),
            profiled: dir.join(PROFILE_MARK).exists(),
            training_error: std::fs::read_to_string(dir.join(TRAINING_ERROR)).ok(),
            dir,
        })
    }

    /// Compiles the instrumented model in `tmp` (`-fprofile-generate`: the
    /// counts go next to its objects), runs `train` on it, writes the
    /// profile and removes the instrumented objects, so that the next
    /// `make` compiles with `-fprofile-use`. The inner result is the
    /// training's.
    fn train(
        tmp: &Path,
        ports: &[Port],
        opts: &BuildOptions,
        ico_patched: bool,
        train: Training,
    ) -> Result<Result<(), String>, VerilatorError> {
        let profile_flags = format!("{OPT_FAST} -fprofile-generate -fprofile-update=single");
        // `-u`: the shim's weak reference alone would not pull libgcov's
        // `__gcov_dump` into the library.
        make(
            tmp,
            &opts.top,
            &profile_flags,
            Some("-fprofile-generate -Wl,-u,__gcov_dump"),
        )?;
        let lib_path = tmp.join("libcosim.so");
        let lib = load_library(&lib_path)?;
        // SAFETY: a function of our shim without arguments.
        let dump: FnVoid = *unsafe { lib.get::<FnVoid>(b"sa_profile_dump") }.map_err(|source| {
            VerilatorError::Load {
                path: lib_path.clone(),
                source,
            }
        })?;
        let build = Arc::new(Build {
            lib,
            ports: ports.to_vec(),
            dir: tmp.to_path_buf(),
            fresh: true,
            options: opts.clone(),
            ico_patched,
            profiled: false,
            training_error: None,
        });
        let trained = train(build.clone());
        // Once dumped, the counts are not written again at the process's end.
        // SAFETY: `sa_profile_dump` calls libgcov's `__gcov_dump`.
        unsafe { dump() };
        drop(build);
        let obj = tmp.join("obj");
        let entries = std::fs::read_dir(&obj).map_err(|source| VerilatorError::Io {
            path: obj.clone(),
            source,
        })?;
        let mut counts = 0;
        for e in entries.flatten() {
            let path = e.path();
            if path.extension().is_some_and(|x| x == "o" || x == "a") {
                let _ = std::fs::remove_file(&path);
            }
            counts += usize::from(path.extension().is_some_and(|x| x == "gcda"));
        }
        let _ = std::fs::remove_file(&lib_path);
        Ok(trained.and_then(|()| {
            if counts == 0 {
                Err("the instrumented model wrote no profile".into())
            } else {
                Ok(())
            }
        }))
    }

    /// Index of a port by name.
    pub fn port(&self, name: &str) -> Result<usize, VerilatorError> {
        self.ports
            .iter()
            .position(|p| p.name == name)
            .ok_or_else(|| VerilatorError::NoPort(name.into()))
    }
}

/// Loads a library built from our shim.
fn load_library(path: &Path) -> Result<libloading::Library, VerilatorError> {
    // SAFETY: the library is one just built from our shim (or its cached
    // copy); loading runs only Verilator's static initialisers.
    unsafe { libloading::Library::new(path) }.map_err(|source| VerilatorError::Load {
        path: path.to_path_buf(),
        source,
    })
}

/// g++ options of the model's fast-path code. -O1: half the compile time
/// of -O2 on rust-hdl's flat Verilog, and no slower here (-O2
/// -march=native measured 19.0 µs a clock against -O1's 17.5 µs on the
/// full field); a profile-guided build adds the profile options.
const OPT_FAST: &str = "-O1";

/// Runs the generated makefile in `tmp/obj` with `opt_fast` for the model's
/// fast-path code (and the shim) and `ldflags` for the link.
fn make(
    tmp: &Path,
    top: &str,
    opt_fast: &str,
    ldflags: Option<&str>,
) -> Result<(), VerilatorError> {
    let mut make = Command::new("make");
    make.args([
        "-j",
        "2",
        "-C",
        "obj",
        "-f",
        &format!("V{top}.mk"),
        &format!("OPT_FAST={opt_fast}"),
        "OPT_SLOW=-O0",
        "OPT_GLOBAL=-O1",
    ]);
    if let Some(ld) = ldflags {
        make.arg(format!("USER_LDFLAGS={ld}"));
    }
    run(&mut make, tmp, "make")
}

/// File in a build's cache directory saying it was compiled with a profile.
const PROFILE_MARK: &str = "profile-guided";

/// File in a build's cache directory holding why its training failed.
const TRAINING_ERROR: &str = "training-error";

/// File in a build's cache directory saying [`patch_ico`] was applied.
const ICO_MARK: &str = "ico-patched";

/// The line of Verilator 5's generated `_eval_triggers__ico` that runs the
/// whole input-combinational ("ico") region on every `eval()`.
const ICO_FIRST: &str = "vlSelf->__VicoTriggered.at(0U) = (0U == vlSelf->__VicoIterCount);";

/// Makes the generated model skip its input-combinational region when no
/// input but the clock changed since the last `eval()`.
///
/// Verilator 5 re-evaluates every combinational process that depends,
/// however indirectly, on a top-level input on the first iteration of
/// every `eval()`. In rust-hdl's Verilog that is most of the design (each
/// module's logic is one `always @(*)` process, and the wire-ins reach the
/// blink tracker combinationally), so with two evaluations per clock the
/// tracker's and the packetiser's logic ran three times a clock. After a
/// clock edge the NBA region re-evaluates whatever the edge changed, so
/// when only the clock moved the region has nothing new to compute —
/// provided no process in it reads the clock, which is checked here: if
/// one does, or the generated code does not have the expected shape (another
/// Verilator version), the model is left as generated (correct, slower).
/// The shim sets `sa_ico_pending` from its own input-written flag before
/// each `eval()`. Returns whether the patch was applied.
fn patch_ico(obj: &Path, clock: &str) -> Result<bool, VerilatorError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| VerilatorError::Io { path, source }
    };
    let mut files = Vec::new();
    for e in std::fs::read_dir(obj).map_err(io(obj))? {
        let path = e.map_err(io(obj))?.path();
        if path.extension().is_some_and(|x| x == "cpp") {
            let text = std::fs::read_to_string(&path).map_err(io(&path))?;
            files.push((path, text));
        }
    }
    let needle = format!("vlSelf->{clock}");
    for (_, text) in &files {
        if ico_reads_clock(text, &needle) {
            return Ok(false);
        }
    }
    let hits: Vec<usize> = (0..files.len())
        .filter(|&i| files[i].1.contains(ICO_FIRST))
        .collect();
    if hits.len() != 1 || files[hits[0]].1.matches(ICO_FIRST).count() != 1 {
        return Ok(false);
    }
    let (path, text) = &files[hits[0]];
    let patched = format!(
        "extern thread_local bool sa_ico_pending;\n{}",
        text.replace(
            ICO_FIRST,
            "vlSelf->__VicoTriggered.at(0U) = (0U == vlSelf->__VicoIterCount) && sa_ico_pending;",
        )
    );
    std::fs::write(path, patched).map_err(io(path))?;
    Ok(true)
}

/// Whether a generated input-combinational function (`..._ico_...(`
/// definitions) reads the clock port `needle` (`vlSelf->clock`).
fn ico_reads_clock(text: &str, needle: &str) -> bool {
    let mut rest = text;
    while let Some(at) = rest.find("___ico_") {
        let line_start = rest[..at].rfind('\n').map_or(0, |i| i + 1);
        let line_end = rest[at..].find('\n').map_or(rest.len(), |i| at + i);
        let line = &rest[line_start..line_end];
        let is_definition = line.ends_with('{') && !line.trim_start().starts_with("//");
        let body_end = if is_definition {
            rest[line_end..]
                .find("\n}\n")
                .map_or(rest.len(), |i| line_end + i)
        } else {
            line_end
        };
        if is_definition {
            let body = &rest[line_end..body_end];
            let mut b = body;
            while let Some(i) = b.find(needle) {
                let next = b[i + needle.len()..].chars().next();
                if !next.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_') {
                    return true;
                }
                b = &b[i + needle.len()..];
            }
        }
        rest = &rest[body_end.max(at + 1)..];
    }
    false
}

fn verilator_version() -> String {
    static V: OnceLock<String> = OnceLock::new();
    V.get_or_init(|| {
        Command::new("verilator")
            .arg("--version")
            .output()
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
            .unwrap_or_default()
    })
    .clone()
}

/// What driving a [`Model`] cost, counted on the Rust side.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    /// Calls into the shim (set, get, eval, tick).
    pub ffi_calls: u64,
    /// `eval()`s of the Verilated model (two per clock: falling and rising edge).
    pub evals: u64,
    /// Of those, the ones that ran the input-combinational region because
    /// an input had been written (see [`Build::ico_patched`]; every `eval()`
    /// runs it when the patch is not applied).
    pub ico_evals: u64,
}

impl Counters {
    /// Adds another's counts.
    pub fn add(&mut self, o: &Counters) {
        self.ffi_calls += o.ffi_calls;
        self.evals += o.evals;
        self.ico_evals += o.ico_evals;
    }
}

/// One instance of a Verilated model (its own `VerilatedContext`).
pub struct Model {
    build: Arc<Build>,
    h: *mut std::ffi::c_void,
    f_eval: FnPtr,
    f_tick: FnTick,
    f_set: FnSet,
    f_get: FnGet,
    f_delete: FnPtr,
    f_trace_open: FnTraceOpen,
    f_trace_close: FnPtr,
    /// Clock cycles run.
    pub cycles: u64,
    /// What driving the model cost: calls and evaluations.
    pub counters: Counters,
    /// An input was written since the last evaluation (the shim's flag
    /// that makes the next `eval()` run the input-combinational region).
    inputs_set: bool,
    dirty: bool,
    buf: Vec<u32>,
}

// SAFETY: the handle is owned by this value alone and Verilator models have
// no thread affinity; the value is moved between threads, never shared.
unsafe impl Send for Model {}

impl Model {
    /// A new instance (all registers as Verilator's `--x-initial fast` leaves them).
    pub fn new(build: Arc<Build>) -> Result<Model, VerilatorError> {
        let load = |path: &Path, e| VerilatorError::Load {
            path: path.to_path_buf(),
            source: e,
        };
        let p = build.dir.join("libcosim.so");
        // SAFETY: symbols of our generated shim with the declared signatures.
        unsafe {
            let f_new: FnNew = *build.lib.get(b"sa_new").map_err(|e| load(&p, e))?;
            let f_eval: FnPtr = *build.lib.get(b"sa_low").map_err(|e| load(&p, e))?;
            let f_tick: FnTick = *build.lib.get(b"sa_tick").map_err(|e| load(&p, e))?;
            let f_set: FnSet = *build.lib.get(b"sa_set").map_err(|e| load(&p, e))?;
            let f_get: FnGet = *build.lib.get(b"sa_get").map_err(|e| load(&p, e))?;
            let f_delete: FnPtr = *build.lib.get(b"sa_delete").map_err(|e| load(&p, e))?;
            let f_trace_open: FnTraceOpen =
                *build.lib.get(b"sa_trace_open").map_err(|e| load(&p, e))?;
            let f_trace_close: FnPtr =
                *build.lib.get(b"sa_trace_close").map_err(|e| load(&p, e))?;
            let h = f_new();
            let mut m = Model {
                build,
                h,
                f_eval,
                f_tick,
                f_set,
                f_get,
                f_delete,
                f_trace_open,
                f_trace_close,
                cycles: 0,
                counters: Counters::default(),
                inputs_set: true,
                dirty: true,
                buf: vec![0; 64],
            };
            m.eval();
            Ok(m)
        }
    }

    /// The build this instance runs.
    pub fn build(&self) -> &Arc<Build> {
        &self.build
    }

    /// Sets input port `i` (see [`Build::port`]) to `v` (ports up to 64 bits).
    #[inline]
    pub fn set(&mut self, i: usize, v: u64) {
        let w = [v as u32, (v >> 32) as u32];
        // SAFETY: the shim reads at most words() ≤ 2 words for such ports.
        unsafe { (self.f_set)(self.h, i as i32, w.as_ptr()) };
        self.counters.ffi_calls += 1;
        self.inputs_set = true;
        self.dirty = true;
    }

    /// Sets a wide input port from 32-bit words (least significant first).
    pub fn set_words(&mut self, i: usize, w: &[u32]) {
        let n = self.build.ports[i].words();
        let mut v = w.to_vec();
        v.resize(n, 0);
        // SAFETY: the shim reads exactly `n` words.
        unsafe { (self.f_set)(self.h, i as i32, v.as_ptr()) };
        self.counters.ffi_calls += 1;
        self.inputs_set = true;
        self.dirty = true;
    }

    /// Reads port `i` (ports up to 64 bits), after settling the logic on
    /// inputs set since the last clock.
    #[inline]
    pub fn get(&mut self, i: usize) -> u64 {
        self.settle();
        let mut w = [0u32; 2];
        // SAFETY: the shim writes at most words() ≤ 2 words for such ports;
        // wider ports write into `buf`.
        if self.build.ports[i].width > 64 {
            return self.get_words(i)[0] as u64;
        }
        unsafe { (self.f_get)(self.h, i as i32, w.as_mut_ptr()) };
        self.counters.ffi_calls += 1;
        w[0] as u64 | (w[1] as u64) << 32
    }

    /// Reads a port of any width as 32-bit words.
    pub fn get_words(&mut self, i: usize) -> Vec<u32> {
        self.settle();
        let n = self.build.ports[i].words();
        if self.buf.len() < n {
            self.buf.resize(n, 0);
        }
        // SAFETY: `buf` holds at least `n` words.
        unsafe { (self.f_get)(self.h, i as i32, self.buf.as_mut_ptr()) };
        self.counters.ffi_calls += 1;
        self.buf[..n].to_vec()
    }

    /// Evaluates the combinational logic if an input changed.
    #[inline]
    pub fn settle(&mut self) {
        if self.dirty {
            self.eval();
        }
    }

    /// Evaluates the model with the clock low (settling the inputs).
    pub fn eval(&mut self) {
        // SAFETY: valid handle.
        unsafe { (self.f_eval)(self.h) };
        self.count_evals(1);
        self.dirty = false;
    }

    /// Counts `n` evaluations, the first of which runs the
    /// input-combinational region if an input was written.
    #[inline]
    fn count_evals(&mut self, n: u64) {
        let c = &mut self.counters;
        c.ffi_calls += 1;
        c.evals += n;
        c.ico_evals += if self.build.ico_patched {
            self.inputs_set as u64
        } else {
            n
        };
        self.inputs_set = false;
    }

    /// Runs `n` clock cycles: settles the inputs with the clock low (if not
    /// done since they changed), then rising edges (and falling edges between).
    #[inline]
    pub fn tick(&mut self, n: u64) {
        if n == 0 {
            return;
        }
        self.settle();
        // SAFETY: valid handle.
        unsafe { (self.f_tick)(self.h, n) };
        // A rising edge, then a falling and a rising edge per further clock.
        self.count_evals(2 * n - 1);
        self.cycles += n;
        // Outputs changed at the edge: the next read settles with the clock low.
        self.dirty = true;
    }

    /// Starts writing a VCD of every signal to `path`; false if the build
    /// has no tracing compiled in.
    pub fn trace_open(&mut self, path: &Path) -> bool {
        let Ok(c) = std::ffi::CString::new(path.to_string_lossy().as_bytes()) else {
            return false;
        };
        // SAFETY: valid handle and NUL-terminated path.
        unsafe { (self.f_trace_open)(self.h, c.as_ptr()) != 0 }
    }

    /// Closes the VCD (flushing it).
    pub fn trace_close(&mut self) {
        // SAFETY: valid handle.
        unsafe { (self.f_trace_close)(self.h) };
    }
}

impl Drop for Model {
    fn drop(&mut self) {
        // SAFETY: the handle was made by sa_new and is deleted once.
        unsafe { (self.f_delete)(self.h) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ports_are_parsed_with_widths() {
        let v = "module cosim(clock,a,b,c);\n input wire clock;\n input wire [31:0] a;\n\
                 output reg [99:0] b;\n output wire c;\nendmodule\nmodule other(x);\n input wire x;\nendmodule\n";
        let p = parse_ports(v, "cosim").unwrap();
        assert_eq!(p.len(), 4);
        assert_eq!(
            p[1],
            Port {
                name: "a".into(),
                dir: Dir::In,
                width: 32
            }
        );
        assert_eq!(p[2].width, 100);
        assert_eq!(p[2].words(), 4);
        assert_eq!(p[3].dir, Dir::Out);
        assert!(parse_ports(v, "nothere").is_err());
        let bad = "module m(a$0);\n input wire a$0;\nendmodule\n";
        assert!(parse_ports(bad, "m").is_err());
    }

    /// A counter, verilated profile-guided: the training drives the
    /// instrumented model, the kept model is compiled with its profile.
    fn counter(tag: u32) -> (String, BuildOptions) {
        let v = format!(
            "// {tag}\nmodule cosim(clock, inc, count);\n input wire clock;\n input wire inc;\n\
             output reg [31:0] count;\n always @(posedge clock) if (inc) count <= count + 32'd{tag};\n\
             initial count = 0;\nendmodule\n"
        );
        let opts = BuildOptions {
            trace: false,
            top: "cosim".into(),
            clock: "clock".into(),
            profile: true,
        };
        (v, opts)
    }

    fn count_after(build: &Arc<Build>, clocks: u64) -> u64 {
        let mut m = Model::new(build.clone()).expect("model");
        let inc = build.port("inc").expect("inc");
        let count = build.port("count").expect("count");
        m.set(inc, 1);
        m.tick(clocks);
        m.get(count)
    }

    #[test]
    fn a_profile_guided_build_runs_its_training_and_keeps_the_behaviour() {
        let (v, opts) = counter(3);
        let trained = std::sync::atomic::AtomicU64::new(0);
        let train = |b: Arc<Build>| -> Result<(), String> {
            assert!(!b.profiled, "the training runs the instrumented model");
            trained.store(count_after(&b, 1000), std::sync::atomic::Ordering::SeqCst);
            Ok(())
        };
        let b = Build::get_trained(&v, &opts, Some(&train)).expect("build");
        assert!(b.profiled && b.training_error.is_none(), "{b:?}");
        if b.fresh {
            assert_eq!(trained.into_inner(), 3000, "the training's own count");
        }
        assert_eq!(count_after(&b, 500), 1500);
    }

    #[test]
    fn a_failed_training_leaves_a_plain_build_that_says_why() {
        let (v, opts) = counter(5);
        let train = |_: Arc<Build>| -> Result<(), String> { Err("no scene".into()) };
        let b = Build::get_trained(&v, &opts, Some(&train)).expect("build");
        assert!(!b.profiled);
        assert_eq!(b.training_error.as_deref(), Some("no scene"));
        assert_eq!(count_after(&b, 7), 35);
    }

    #[test]
    fn scheduling_hints_after_a_port_are_skipped() {
        let v = "module m(a,b);\n input wire [3:0] a;\n output reg b /*verilator isolate_assignments*/;\nendmodule\n";
        let p = parse_ports(v, "m").unwrap();
        assert_eq!(p[1].name, "b");
        assert_eq!(p[1].dir, Dir::Out);
        assert_eq!(without_block_comments("x /* a */ y /* b"), "x  y ");
    }

    /// Generated-code shapes of Verilator 5.006: the trigger line and an
    /// input-combinational function.
    fn generated(ico_body: &str) -> (String, String) {
        let triggers = format!(
            "#include \"verilated.h\"\nvoid V___eval_triggers__ico(V* vlSelf) {{\n    // Body\n    {ICO_FIRST}\n}}\n"
        );
        let comb = format!(
            "void V___024root___ico_comb__TOP__0(V* vlSelf);\n\
             VL_INLINE_OPT void V___024root___ico_comb__TOP__0(V* vlSelf) {{\n{ico_body}\n}}\n\
             void V___024root___nba_sequent__TOP__0(V* vlSelf) {{\n    x = vlSelf->clock;\n}}\n"
        );
        (triggers, comb)
    }

    fn patch_in(dir: &str, ico_body: &str) -> (bool, String) {
        let d = std::env::temp_dir().join(format!("smartagg-ico-{dir}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        let (t, c) = generated(ico_body);
        std::fs::write(d.join("a.cpp"), t).unwrap();
        std::fs::write(d.join("b.cpp"), c).unwrap();
        let patched = patch_ico(&d, "clock").unwrap();
        let text = std::fs::read_to_string(d.join("a.cpp")).unwrap();
        let _ = std::fs::remove_dir_all(&d);
        (patched, text)
    }

    #[test]
    fn ico_region_is_gated_when_no_ico_process_reads_the_clock() {
        // `clock_enable` is another port: not a read of `clock`.
        let (patched, text) = patch_in("ok", "    y = vlSelf->clock_enable & vlSelf->a;");
        assert!(patched);
        assert!(text.starts_with("extern thread_local bool sa_ico_pending;"));
        assert!(text.contains("(0U == vlSelf->__VicoIterCount) && sa_ico_pending;"));
        assert!(!text.contains(ICO_FIRST));
    }

    #[test]
    fn ico_region_is_left_alone_when_a_process_reads_the_clock() {
        let (patched, text) = patch_in("clock", "    y = vlSelf->clock & vlSelf->a;");
        assert!(!patched);
        assert!(text.contains(ICO_FIRST));
        assert!(!text.contains("sa_ico_pending"));
    }
}
