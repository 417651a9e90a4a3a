//! The tracker's sequencer against the rules of its doc (the tracker as a
//! whole is checked against the model in `blink_tracker.rs`): 100,000 clocks
//! of random events — the queue's room, the decide stage's end-of-row steps
//! and last rows, the walks' last slots, drain words — through streams
//! that stop 0 to 2 planes ahead of the tracker (one in five before its
//! first plane) with N from 1 to 3, restarted (with and without
//! StreamStart) at random and after each StreamEnd. Every clock: the
//! state, the plane t and its rows, `t ≥ N` and `t + 1 ≥ N`, `finishing`,
//! the walk's start and the drain pop.

mod common;

use rand::Rng;
use smartagg_hdl::blink_tracker::{Sequencer, TrackerState as S};
use smartagg_hdl::testbench::bench::{settle, Bench};

const NW: usize = 4;

/// The sequencer as its doc states it.
struct Want {
    state: S,
    t: u64,
    rows: u64,
    /// `t + 1 = p + N`, a clock old.
    drain_end: bool,
}

#[test]
fn sequencer_follows_a_stream_from_start_to_end() {
    let mut b = Bench::new(Sequencer::<NW>::default(), |u| &mut u.clock);
    let mut rng = common::rng(5);
    let mut w = Want {
        state: S::Done,
        t: 0,
        rows: 0,
        drain_end: false,
    };
    let (mut n, mut p, mut stopping) = (1u64, 0u64, false);
    // Clocks entered in each state; walks started from Run into Finish,
    // streams ended at t = 0 (Finish straight to End), drain planes
    // started after the last (Emit), restarts without StreamStart.
    let mut entered = std::collections::HashMap::new();
    let mut seen = [0u32; 4];
    for clock in 0..100_000 {
        let restart = match w.state {
            S::Done => rng.gen_bool(0.2),
            _ => rng.gen_bool(0.0005),
        };
        let emit_start = rng.gen_bool(0.8);
        if restart {
            n = rng.gen_range(1..4);
            // One stream in five stops before its first plane.
            stopping = rng.gen_bool(0.2);
            p = 0;
        }
        // The host stops the stream some planes ahead of the tracker.
        if !stopping && rng.gen_bool(0.01) {
            stopping = true;
            p = w.t + rng.gen_range(0..3);
        }
        let room = rng.gen_bool(0.6);
        let step = rng.gen_bool(0.3);
        let lastrow = rng.gen_bool(0.3);
        let row = rng.gen_range(0..1024u64);
        let walked = rng.gen_bool(0.2);
        let in_valid = rng.gen_bool(0.7);
        let in_flush = rng.gen_bool(0.8);
        let in_y = rng.gen_range(0..1024u64);
        let head_eor = rng.gen_bool(0.4);
        let head_lastrow = rng.gen_bool(0.3);

        let u = &mut b.uut;
        u.restart.next = restart;
        u.emit_start.next = emit_start;
        u.n_window.next = n.into();
        u.stopping.next = stopping;
        u.planes_total.next = p.into();
        u.room.next = room;
        u.step.next = step;
        u.lastrow.next = lastrow;
        u.row.next = row.into();
        u.walked.next = walked;
        u.in_valid.next = in_valid;
        u.in_flush.next = in_flush;
        u.in_y.next = in_y.into();
        u.head_eor.next = head_eor;
        u.head_lastrow.next = head_lastrow;
        settle(u);

        // This clock's outputs, and the next clock's state.
        let finishing = stopping && w.t == p;
        let (mut start_walk, mut drain_pop) = (false, false);
        let mut next = Want {
            state: w.state,
            t: w.t,
            rows: w.rows,
            drain_end: w.t + 1 == p + n,
        };
        match w.state {
            S::Start if room => next.state = S::Run,
            S::Run if finishing => {
                start_walk = w.t != 0;
                next.state = S::Finish;
                seen[0] += start_walk as u32;
            }
            S::Run if step => {
                next.rows = row + 1;
                if lastrow {
                    start_walk = true;
                    next.state = S::Walk;
                }
            }
            S::Walk if walked => next.state = S::WalkEnd,
            S::WalkEnd => {
                next.t = w.t + 1;
                next.rows = 0;
                next.state = S::Run;
            }
            S::Finish if w.t == 0 => {
                next.state = S::End;
                seen[1] += 1;
            }
            S::Finish if walked => next.state = S::Drain,
            S::Drain if in_valid => {
                drain_pop = true;
                if in_flush && head_eor {
                    next.rows = in_y + 1;
                    if head_lastrow {
                        start_walk = true;
                        next.state = S::DrainWalk;
                    }
                }
            }
            S::DrainWalk if walked => {
                next.t = w.t + 1;
                next.rows = 0;
                next.state = S::Drain;
                if w.drain_end {
                    start_walk = true;
                    next.state = S::Emit;
                    seen[2] += 1;
                }
            }
            S::Emit if walked => next.state = S::End,
            S::End if room => next.state = S::Done,
            _ => {}
        }
        if restart {
            next.state = if emit_start { S::Start } else { S::Done };
            next.t = 0;
            next.rows = 0;
            seen[3] += !emit_start as u32;
        }

        let u = &b.uut;
        let flags = [
            (u.stream_start.val(), S::Start),
            (u.run.val(), S::Run),
            (u.walk.val(), S::Walk),
            (u.walk_end.val(), S::WalkEnd),
            (u.finish.val(), S::Finish),
            (u.drain_walk.val(), S::DrainWalk),
            (u.emit.val(), S::Emit),
            (u.stream_end.val(), S::End),
            (u.done.val(), S::Done),
        ];
        for (flag, state) in flags {
            assert_eq!(
                flag,
                w.state == state,
                "clock {clock}: {state:?} in {:?}",
                w.state
            );
        }
        assert_eq!(u.t.val().to_u64(), w.t, "clock {clock}: t");
        assert_eq!(u.rows.val().to_u64(), w.rows, "clock {clock}: rows");
        assert_eq!(u.t_ge_n.val(), w.t >= n, "clock {clock}: t ≥ N");
        assert_eq!(u.t1_ge_n.val(), w.t + 1 >= n, "clock {clock}: t + 1 ≥ N");
        assert_eq!(u.finishing.val(), finishing, "clock {clock}: finishing");
        assert_eq!(u.start_walk.val(), start_walk, "clock {clock}: walk start");
        assert_eq!(u.drain_pop.val(), drain_pop, "clock {clock}: drain pop");

        if next.state != w.state {
            *entered.entry(format!("{:?}", next.state)).or_insert(0u32) += 1;
        }
        b.tick();
        w = next;
    }
    assert_eq!(entered.len(), 10, "states entered {entered:?}");
    assert!(
        entered.values().chain(&seen).all(|&k| k >= 20),
        "coverage {entered:?} {seen:?}"
    );
}
