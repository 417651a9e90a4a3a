//! The top module's port table, read from the Verilog text: what the shim
//! numbers and the harnesses look up by name.

use super::VerilatorError;

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

    #[test]
    fn scheduling_hints_after_a_port_are_skipped() {
        let v = "module m(a,b);\n input wire [3:0] a;\n output reg b /*verilator isolate_assignments*/;\nendmodule\n";
        let p = parse_ports(v, "m").unwrap();
        assert_eq!(p[1].name, "b");
        assert_eq!(p[1].dir, Dir::Out);
        assert_eq!(without_block_comments("x /* a */ y /* b"), "x  y ");
    }
}
