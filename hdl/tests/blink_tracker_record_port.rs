//! The blink tracker's record port against the rules of its doc (the
//! tracker as a whole is checked against the model in `blink_tracker.rs`):
//! 40,000 clocks, each asking for one record or none (StreamStart, a Blink
//! of the walk or of the stream end's emit, the plane's Dropped record with
//! or without drops, StreamEnd) with random fields, the queue's room in
//! phases of plenty and of scarcity, the free bank shown or not, and
//! restarts. Every clock: whether it pushes, the descriptor it pushes,
//! whether the slot takes the free bank, and the lost-record count it
//! carries.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
// The kinds as the packetiser reads them: the port writes them as literals
// (`hdl_gen` takes no path constant), so this ties the two.
use smartagg_hdl::blink_tracker::record_kind::{BLINK, DROPPED, END, START};
use smartagg_hdl::blink_tracker::RecordPort;
use smartagg_hdl::testbench::bench::{settle, Bench};

const BW: usize = 6;
const MASK48: u64 = (1 << 48) - 1;

/// What a clock asks for.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Ask {
    None,
    Start,
    Blink { emit: bool },
    WalkEnd,
    End,
}

/// The descriptor pushed: kind, slot, flags, ax, ay, t0, t1, tag, bank.
type Descriptor = (u64, u64, u64, u64, u64, u64, u64, u64, u64);

#[test]
fn record_port_pushes_each_record_and_counts_the_lost() {
    let mut b = Bench::new(RecordPort::<BW>::default(), |u| &mut u.clock);
    let mut rng = common::rng(83);
    let mut lost = 0u64;
    let mut room_rate = 0.9;
    // Seen: pushes of StreamStart, Blink, Dropped, StreamEnd; Blinks lost
    // for want of room, for want of a bank; Dropped records lost; waits of
    // StreamStart and StreamEnd; restarts over a nonzero count; records
    // pushed after 3 or more lost; emit's tags.
    let mut seen = [0u32; 12];
    for clock in 0..40_000 {
        if clock % 500 == 0 {
            room_rate = if rng.gen_bool(0.5) { 0.9 } else { 0.2 };
        }
        let restart = clock == 0 || rng.gen_bool(0.002);
        let ask = match rng.gen_range(0..10) {
            0 => Ask::Start,
            1..=4 => Ask::Blink {
                emit: rng.gen_bool(0.3),
            },
            5 | 6 => Ask::WalkEnd,
            7 => Ask::End,
            _ => Ask::None,
        };
        let room = rng.gen_bool(room_rate);
        let fb_valid = rng.gen_bool(0.8);
        let t = if rng.gen_bool(0.05) {
            0
        } else {
            rng.gen::<u64>() & MASK48
        };
        let slot = rng.gen::<u64>() & 0xff;
        let flags = rng.gen::<u64>() & 0xff;
        let (ax, ay) = (rng.gen::<u64>() & 1023, rng.gen::<u64>() & 1023);
        let (t_cross, t_drop) = (rng.gen::<u64>() & MASK48, rng.gen::<u64>() & MASK48);
        let bank = rng.gen::<u64>() & ((1 << BW) - 1);
        let plane_drops = if rng.gen_bool(0.3) {
            0
        } else {
            rng.gen::<u32>() as u64
        };
        let (first_x, first_y) = (rng.gen::<u64>() & 1023, rng.gen::<u64>() & 1023);

        let u = &mut b.uut;
        u.restart.next = restart;
        u.record.room.next = room;
        u.fb_valid.next = fb_valid;
        u.t.next = t.to_bits();
        u.stream_start.next = ask == Ask::Start;
        u.blink.next = matches!(ask, Ask::Blink { .. });
        u.emit.next = ask == Ask::Blink { emit: true } || (ask == Ask::None && rng.gen());
        u.slot.next = slot.to_bits();
        u.flags.next = flags.to_bits();
        u.ax.next = ax.to_bits();
        u.ay.next = ay.to_bits();
        u.t_cross.next = t_cross.to_bits();
        u.t_drop.next = t_drop.to_bits();
        u.bank.next = bank.to_bits();
        u.walk_end.next = ask == Ask::WalkEnd;
        u.plane_drops.next = plane_drops.to_bits();
        u.first_x.next = first_x.to_bits();
        u.first_y.next = first_y.to_bits();
        u.stream_end.next = ask == Ask::End;
        settle(u);

        // The rules: what is pushed, whether the slot takes the bank, and
        // the count after the clock.
        let (push, descriptor, fb_pop, counted): (bool, Option<Descriptor>, bool, bool) = match ask
        {
            Ask::None => (false, None, false, false),
            Ask::Start => (room, Some((START, 0, 0, 0, 0, 0, 0, t, 0)), false, false),
            Ask::Blink { emit } => {
                let tag = if emit { t.wrapping_sub(1) & MASK48 } else { t };
                let pushed = room && fb_valid;
                let d = (BLINK, slot, flags, ax, ay, t_cross, t_drop, tag, bank);
                (pushed, Some(d), pushed, true)
            }
            Ask::WalkEnd if plane_drops == 0 => (false, None, false, false),
            Ask::WalkEnd => {
                let d = (DROPPED, 0, 0, first_x, first_y, t, plane_drops, t, 0);
                (room, Some(d), false, true)
            }
            Ask::End => (room, Some((END, 0, 0, 0, 0, 0, 0, t, 0)), false, false),
        };
        let r = &u.record;
        assert_eq!(r.push.val(), push, "clock {clock}: push ({ask:?})");
        assert_eq!(u.fb_pop.val(), fb_pop, "clock {clock}: fb_pop ({ask:?})");
        assert_eq!(r.lost.val().to_u64(), lost, "clock {clock}: lost");
        if push {
            let got = (
                r.kind.val().to_u64(),
                r.slot.val().to_u64(),
                r.flags.val().to_u64(),
                r.ax.val().to_u64(),
                r.ay.val().to_u64(),
                r.t0.val().to_u64(),
                r.t1.val().to_u64(),
                r.tag.val().to_u64(),
                r.bank.val().to_u64(),
            );
            assert_eq!(Some(got), descriptor, "clock {clock}: the descriptor");
            seen[match ask {
                Ask::Start => 0,
                Ask::Blink { .. } => 1,
                Ask::WalkEnd => 2,
                _ => 3,
            }] += 1;
            seen[9] += (lost >= 3) as u32;
            seen[10] += (ask == Ask::Blink { emit: true }) as u32;
        } else {
            match ask {
                Ask::Blink { .. } if !room => seen[4] += 1,
                Ask::Blink { .. } => seen[5] += 1,
                Ask::WalkEnd if plane_drops != 0 => seen[6] += 1,
                Ask::Start | Ask::End => seen[7] += 1,
                _ => {}
            }
        }
        b.tick();
        seen[8] += (restart && lost != 0) as u32;
        seen[11] += (restart && counted && !push) as u32;
        lost = if restart || push && ask != Ask::Start {
            0
        } else if counted && !push {
            (lost + 1) & 0xffff_ffff
        } else {
            lost
        };
    }
    assert!(
        seen[..11].iter().all(|&n| n >= 20) && seen[11] >= 1,
        "coverage {seen:?}"
    );
}
