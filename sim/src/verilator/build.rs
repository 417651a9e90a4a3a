//! Verilating a design into a loaded library: the build options, the
//! on-disk cache and its key, the tools run, and the process-wide build
//! table.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex, OnceLock};

use super::ico::patch_ico;
use super::shim::shim_source;
use super::{parse_ports, Dir, Port, VerilatorError};

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

type FnVoid = unsafe extern "C" fn();

/// A Verilated design, built (or found in the cache) and loaded.
pub struct Build {
    pub(super) lib: libloading::Library,
    /// The top's ports, in the order the shim numbers them.
    pub ports: Vec<Port>,
    /// The cache directory of this build.
    pub dir: PathBuf,
    /// Whether it was verilated now (false: found in the cache).
    pub fresh: bool,
    /// The options it was built with.
    pub options: BuildOptions,
    /// The input-combinational region is skipped on clock-only evaluations
    /// (the patch and why: `verilator/ico.rs`).
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::verilator::Model;

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
}
