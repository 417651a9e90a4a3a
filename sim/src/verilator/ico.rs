//! Patching Verilator's generated C++ so that clock-only evaluations skip
//! the input-combinational region.

use std::path::Path;

use super::VerilatorError;

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
pub(super) fn patch_ico(obj: &Path, clock: &str) -> Result<bool, VerilatorError> {
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

#[cfg(test)]
mod tests {
    use super::*;

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
