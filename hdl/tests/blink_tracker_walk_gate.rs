//! The gate of the walk's W2 (the tracker as a whole is checked against
//! the model in `blink_tracker.rs`): 40,000 clocks of random inputs, in one
//! of the four walks or none, against the rules of its doc. Every clock:
//! * no write without W2's slot, and only the current walk's;
//! * the end of a plane and of a drain plane write only once the sweep
//!   had finished plane t − 1 a clock ago;
//! * a Blink (a completed segment at the end of a plane, a busy slot in
//!   `emit`) waits exactly when the record queue has room and the free list
//!   shows no bank; with the queue full, or a bank shown, it goes ahead;
//! * `finish` never waits;
//! * every write is `done`, every write but `emit`'s goes back to the walk
//!   memory.

mod common;

use rand::Rng;
use smartagg_hdl::blink_tracker::WalkGate;
use smartagg_hdl::testbench::bench::{settle, Bench};

#[test]
fn walk_gate_waits_for_the_sweep_and_for_a_blinks_bank() {
    let mut b = Bench::new(WalkGate::default(), |u| &mut u.clock);
    let mut rng = common::rng(38);
    // `view_free` a clock ago (none at power-up).
    let mut swept_before = false;
    // Seen, by walk (end of plane, finish, drain, emit): writes; and
    // Blinks that wait, Blinks pushed with a bank, Blinks that go ahead
    // into a full queue, end-of-plane slots held by the sweep, drain slots
    // held by the sweep, walks without a slot, non-Blink writes.
    let mut writes = [0u32; 4];
    let mut seen = [0u32; 7];
    for clock in 0..40_000 {
        let walk = rng.gen_range(0..5); // 4: none
        let view_free = rng.gen_bool(0.7);
        let valid = rng.gen_bool(0.8);
        let comp = rng.gen_bool(0.5);
        let was_busy = rng.gen_bool(0.6);
        let room = rng.gen_bool(0.7);
        let fb_valid = rng.gen_bool(0.5);

        let u = &mut b.uut;
        u.end_of_plane.next = walk == 0;
        u.finish.next = walk == 1;
        u.drain.next = walk == 2;
        u.emit.next = walk == 3;
        u.view_free.next = view_free;
        u.valid.next = valid;
        u.comp.next = comp;
        u.was_busy.next = was_busy;
        u.room.next = room;
        u.fb_valid.next = fb_valid;
        settle(u);

        // Held by the sweep (the ROI view of t − 1 is still read).
        let held = (walk == 0 || walk == 2) && !swept_before;
        // Would make a Blink record if written.
        let blinks = (walk == 0 && comp) || (walk == 3 && was_busy);
        let waits = valid && !held && blinks && room && !fb_valid;
        let write = valid && walk < 4 && !held && !waits;
        let we = [
            u.we_walk.val(),
            u.we_fin.val(),
            u.we_drain.val(),
            u.we_emit.val(),
        ];
        for (k, &w) in we.iter().enumerate() {
            assert_eq!(w, write && walk == k, "clock {clock}: write enable {k}");
        }
        assert_eq!(u.bank_wait.val(), waits, "clock {clock}: bank wait");
        assert_eq!(u.blink.val(), write && blinks, "clock {clock}: blink");
        assert_eq!(u.done.val(), write, "clock {clock}: done");
        assert_eq!(
            u.write_back.val(),
            write && walk != 3,
            "clock {clock}: write back"
        );

        if write {
            writes[walk] += 1;
        }
        seen[0] += waits as u32;
        seen[1] += (write && blinks && room) as u32;
        seen[2] += (write && blinks && !room) as u32;
        seen[3] += (valid && walk == 0 && held) as u32;
        seen[4] += (valid && walk == 2 && held) as u32;
        seen[5] += (!valid && walk < 4) as u32;
        seen[6] += (write && !blinks) as u32;
        b.tick();
        swept_before = view_free;
    }
    assert!(
        writes.iter().chain(&seen).all(|&n| n >= 100),
        "coverage {writes:?} {seen:?}"
    );
}
