#!/usr/bin/env python3
"""Read a smartagg blink-ROI packet stream (.rois).

A second decoder of the stream, written from model/PACKETS.md alone (plain
Python 3, standard library only); section numbers below refer to that file.

    python3 tools/rois.py FILE.rois        # JSON lines on stdout (PACKETS.md §9)
    python3 tools/rois.py - < FILE.rois    # the same from stdin

Each line is one JSON object: a record, a sequence gap or a run of skipped
bytes, in stream order, then one summary object with the loss accounting
(§6). `smartagg inspect FILE.rois --json` prints the same bytes.

As a library:

    import rois
    for obj in rois.decode(open("blinks.rois", "rb").read()):
        if obj["type"] == "blink":
            print(obj["anchor_x"], obj["anchor_y"], obj["planes_summed"])
"""

import json
import sys

MAGIC = b"SA"  # 0x53 0x41
VERSION = 3  # newest version read; versions 1 and 2 are read too
MAX_PAYLOAD = 4096
HEADER_LEN = 10
CRC_LEN = 4
BLINK_FIXED_LEN = 35
ESCAPE_Q = 32


def _crc32c_table():
    table = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = (c >> 1) ^ 0x82F63B78 if c & 1 else c >> 1
        table.append(c)
    return table


_CRC_TABLE = _crc32c_table()


def crc32c(data):
    """CRC-32C (Castagnoli), reflected, init and final XOR 0xFFFFFFFF (§2)."""
    c = 0xFFFFFFFF
    table = _CRC_TABLE
    for b in data:
        c = (c >> 8) ^ table[(c ^ b) & 0xFF]
    return c ^ 0xFFFFFFFF


assert crc32c(b"123456789") == 0xE3069283


class Malformed(Exception):
    """A CRC-valid payload that fails a check of §3 or §4."""


def _u(b, off, n):
    return int.from_bytes(b[off:off + n], "little")


def _i48(b, off):
    v = _u(b, off, 6)
    return v - (1 << 48) if v >= 1 << 47 else v


def _roi_size_ok(r):
    return r % 2 == 1 and 1 <= r <= 31


def decode_counts(block, n):
    """The n counts of a count block (§4); Malformed if the block is invalid."""
    # base: unsigned LEB128, 1 to 5 bytes, < 2^32, no trailing 0x00 group.
    base = 0
    i = 0
    while True:
        if i >= len(block):
            raise Malformed("count block ends inside the base varint")
        byte = block[i]
        if i == 4 and byte > 0x0F:
            raise Malformed("base varint over 32 bits")
        base |= (byte & 0x7F) << (7 * i)
        i += 1
        if byte & 0x80 == 0:
            if i > 1 and byte == 0:
                raise Malformed("base varint has a redundant trailing group")
            break
    if i >= len(block):
        raise Malformed("count block ends before k")
    k = block[i]
    if k > 31:
        raise Malformed("k > 31")
    codes = block[i + 1:]
    total = len(codes) * 8
    pos = 0

    def take(nbits):
        # The next nbits bits, most significant first.
        nonlocal pos
        if pos + nbits > total:
            raise Malformed("count block ends inside a code")
        first, last = pos >> 3, (pos + nbits + 7) >> 3
        window = int.from_bytes(codes[first:last], "big")
        v = (window >> (8 * (last - first) - (pos & 7) - nbits)) & ((1 << nbits) - 1)
        pos += nbits
        return v

    counts = []
    for _ in range(n):
        # Unary quotient: up to 32 one-bits; 32 of them are an escape.
        q = 0
        while q < ESCAPE_Q:
            if take(1) == 0:
                break
            q += 1
        if q == ESCAPE_Q:
            d = take(32)
            if d >> k < ESCAPE_Q:
                raise Malformed("escape for an offset with a regular code")
        else:
            d = (q << k) | take(k)
        c = base + d
        if c > 0xFFFFFFFF:
            raise Malformed("count above 2^32 - 1")
        counts.append(c)
    pad = (-pos) % 8
    if pad and take(pad) != 0:
        raise Malformed("non-zero padding")
    if pos != total:
        raise Malformed("bytes after the last count")
    return counts


def decode_payload(version, kind, seq, p):
    """The record of a CRC-valid frame of version 1, 2 or 3 (§3), as a dict
    in the key order of §9; Malformed if the payload is invalid."""
    if kind == 0x01:
        fixed = {1: 33, 2: 37}.get(version, 41)
        if len(p) < fixed:
            raise Malformed("stream-start too short")
        n = p[24]
        if len(p) != fixed + 2 * n:
            raise Malformed("stream-start length")
        roi_size = p[22]
        if not _roi_size_ok(roi_size):
            raise Malformed("roi_size")
        threshold_int = _u(p, 8, 4)
        after = 25 + 2 * n
        return {
            "type": "stream_start",
            "seq": seq,
            "width": _u(p, 0, 2),
            "height": _u(p, 2, 2),
            "n_window": _u(p, 4, 4),
            "threshold_int": threshold_int,
            # Version 1 has no threshold_hold: it equals threshold_int.
            "threshold_hold": _u(p, after + 8, 4) if version >= 2 else threshold_int,
            # Versions 1 and 2 have no end_trim (their segments summed to t_drop).
            "end_trim": _u(p, after + 12, 4) if version >= 3 else None,
            "l_min": _u(p, 12, 4),
            "l_max": _u(p, 16, 4),
            "r_assoc": p[20],
            "slots": p[21],
            "roi_size": roi_size,
            "kernel_shift": p[23],
            "kernel": [_u(p, 25 + 2 * j, 2) for j in range(n)],
            "plane_period_ns": _u(p, after, 4),
            "masked_pixels": _u(p, after + 4, 4),
        }
    if kind == 0x02:
        if len(p) < BLINK_FIXED_LEN:
            raise Malformed("blink too short")
        roi_size = p[34]
        if not _roi_size_ok(roi_size):
            raise Malformed("roi_size")
        counts = decode_counts(p[BLINK_FIXED_LEN:], roi_size * roi_size)
        return {
            "type": "blink",
            "seq": seq,
            "slot": p[0],
            "flags": p[1],
            "anchor_x": _u(p, 2, 2),
            "anchor_y": _u(p, 4, 2),
            "t_cross": _u(p, 6, 6),
            "t_drop": _u(p, 12, 6),
            "t_s": _i48(p, 18),
            "t_e": _i48(p, 24),
            "planes_summed": _u(p, 30, 4),
            "roi_size": roi_size,
            "counts": counts,
        }
    if kind == 0x03:
        if len(p) != 14:
            raise Malformed("dropped length")
        return {
            "type": "dropped",
            "seq": seq,
            "plane": _u(p, 0, 6),
            "count": _u(p, 6, 4),
            "first_x": _u(p, 10, 2),
            "first_y": _u(p, 12, 2),
        }
    if kind == 0x04:
        if len(p) != 48:
            raise Malformed("stream-end length")
        names = ["planes", "blinks", "unconfirmed", "dropped_candidates",
                 "bridged_dips", "cut_segments"]
        rec = {"type": "stream_end", "seq": seq}
        for j, name in enumerate(names):
            rec[name] = _u(p, 8 * j, 8)
        return rec
    if kind == 0x7F:
        if len(p) != 8:
            raise Malformed("overflow length")
        first_seq, count = _u(p, 0, 4), _u(p, 4, 4)
        if count == 0 or first_seq != seq:
            raise Malformed("overflow count 0 or first_seq not the header's")
        return {"type": "overflow", "seq": seq, "first_seq": first_seq, "count": count}
    raise Malformed("unknown record type")


def decode(data):
    """Every event of the stream `data` (bytes), in order (§6), then the
    summary; each a dict in the key order of §9."""
    data = bytes(data)
    end = len(data)
    stats = {
        "type": "summary",
        "packets_ok": 0,
        "bytes_in": end,
        "crc_errors": 0,
        "malformed": 0,
        "bytes_skipped": 0,
        "lost_in_transport": 0,
        "lost_on_device": 0,
        "newer_version": 0,
        "truncated_tail_bytes": 0,
        "out_of_order": 0,
    }
    events = []
    expected = 0
    run = 0  # bytes of the current run of skipped bytes
    tail_from = None  # offset in the run of the first short header

    def flush():
        nonlocal run, tail_from
        if run == 0:
            return
        t = run if tail_from is None else tail_from
        if t > 0:
            stats["bytes_skipped"] += t
            events.append({"type": "skipped", "bytes": t, "reason": "corrupt"})
        if run - t > 0:
            stats["truncated_tail_bytes"] += run - t
            events.append({"type": "skipped", "bytes": run - t, "reason": "truncated"})
        run = 0
        tail_from = None

    def advance_to(s):
        nonlocal expected
        d = (s - expected) % (1 << 32)
        if d == 0:
            return
        if d < 1 << 31:
            stats["lost_in_transport"] += d
            lost = d
        else:
            stats["out_of_order"] += 1
            lost = 0
        events.append({"type": "gap", "expected": expected, "got": s,
                       "lost": lost, "on_device": False})

    def deliver(rec):
        nonlocal expected
        if rec["type"] == "overflow":
            f, n = rec["first_seq"], rec["count"]
            advance_to(f)
            got = (f + n) % (1 << 32)
            stats["lost_on_device"] += n
            events.append({"type": "gap", "expected": f, "got": got,
                           "lost": n, "on_device": True})
            expected = got
        elif rec["type"] == "stream_start" and rec["seq"] == 0:
            expected = 1  # a new stream: no gap
        else:
            advance_to(rec["seq"])
            expected = (rec["seq"] + 1) % (1 << 32)
        stats["packets_ok"] += 1
        events.append(rec)

    p = 0
    while p < end:
        if data[p] != MAGIC[0]:
            q = data.find(MAGIC[:1], p)
            q = end if q < 0 else q
            run += q - p
            p = q
            continue
        r = end - p
        # short: a header cut off by the end of the stream (§6 step 4).
        short = False
        if r < 2:
            short = True
        elif data[p + 1] != MAGIC[1]:
            pass
        elif r < 3:
            short = True
        elif data[p + 2] == 0:
            pass
        elif r < HEADER_LEN:
            short = True
        else:
            length = _u(data, p + 8, 2)
            if length <= MAX_PAYLOAD:
                total = HEADER_LEN + length + CRC_LEN
                if r < total:
                    short = True
                elif crc32c(data[p:p + HEADER_LEN + length]) != _u(data, p + HEADER_LEN + length, 4):
                    stats["crc_errors"] += 1
                else:
                    frame = data[p:p + total]
                    p += total
                    tail_from = None
                    flush()
                    version, kind, seq = frame[2], frame[3], _u(frame, 4, 4)
                    if version > VERSION:
                        stats["newer_version"] += 1
                        stats["bytes_skipped"] += total
                        events.append({"type": "skipped", "bytes": total,
                                       "reason": "newer_version", "version": version})
                        continue
                    try:
                        rec = decode_payload(version, kind, seq, frame[HEADER_LEN:total - CRC_LEN])
                    except Malformed:
                        stats["malformed"] += 1
                        stats["bytes_skipped"] += total
                        events.append({"type": "skipped", "bytes": total, "reason": "malformed"})
                        continue
                    deliver(rec)
                    continue
        if short and tail_from is None:
            tail_from = run
        run += 1
        p += 1
    flush()
    events.append(stats)
    return events


def main(argv):
    if len(argv) != 2 or argv[1] in ("-h", "--help"):
        sys.stderr.write("usage: python3 tools/rois.py FILE.rois   (or - for stdin)\n")
        return 2
    if argv[1] == "-":
        data = sys.stdin.buffer.read()
    else:
        with open(argv[1], "rb") as f:
            data = f.read()
    out = sys.stdout
    newest = None
    for obj in decode(data):
        out.write(json.dumps(obj, separators=(",", ":")))
        out.write("\n")
        if obj["type"] == "skipped" and obj["reason"] == "newer_version":
            newest = max(newest or 0, obj["version"])
    if newest is not None:
        sys.stderr.write("stream format version %d is newer than this decoder supports (%d)\n"
                         % (newest, VERSION))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
