//! One loaded instance of a Verilated model, driven through the shim's
//! entry points, and what driving it cost.

use std::path::Path;
use std::sync::Arc;

use super::{Build, VerilatorError};

type FnNew = unsafe extern "C" fn() -> *mut std::ffi::c_void;
type FnPtr = unsafe extern "C" fn(*mut std::ffi::c_void);
type FnTick = unsafe extern "C" fn(*mut std::ffi::c_void, u64);
type FnSet = unsafe extern "C" fn(*mut std::ffi::c_void, i32, *const u32);
type FnGet = unsafe extern "C" fn(*mut std::ffi::c_void, i32, *mut u32);
type FnTraceOpen = unsafe extern "C" fn(*mut std::ffi::c_void, *const std::ffi::c_char) -> i32;

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
