#!/usr/bin/env python3
"""Writes a Verilog file with its modules in the reverse order: the same
lines, each module's attribute lines (such as `(* blackbox *)`) kept with
it, and checks that the two files hold the same multiset of lines.

Used to measure how far a synthesis result depends on the order in which
yosys reads the design (hdl/RESOURCES.md, 2026-11-28 evening):

    smartagg hdl generate --preset spcimager --objective 150 --out g150
    python3 tools/reverse_modules.py g150/top.v rev/top.v
    smartagg hdl resources --verilog rev/top.v --work revw --json
"""
import sys


def reverse_modules(text):
    preamble, modules, current, pending = [], [], None, []
    for line in text.split("\n"):
        if line.startswith("(*") and line.rstrip().endswith("*)"):
            pending.append(line)
            continue
        if line.startswith("module "):
            if current is not None:
                modules.append(current)
            current, pending = pending + [line], []
            continue
        target = preamble if current is None else current
        target.extend(pending)
        pending = []
        target.append(line)
    if current is not None:
        modules.append(current)
    body = "\n".join("\n".join(m) for m in reversed(modules))
    return "\n".join(preamble) + "\n" + body, len(modules)


def main():
    if len(sys.argv) != 3 or sys.argv[1] == sys.argv[2]:
        sys.exit("usage: reverse_modules.py IN.v OUT.v (two different files)")
    text = open(sys.argv[1]).read()
    out, n = reverse_modules(text)
    if sorted(text.split("\n")) != sorted(out.split("\n")):
        sys.exit("the reordered file does not hold the same lines: not written")
    with open(sys.argv[2], "w") as f:
        f.write(out)
    print(f"{n} modules reversed into {sys.argv[2]}")


if __name__ == "__main__":
    main()
