//! The tracker's sequencer: its state, the plane t it tracks and the rows
//! of t done, from StreamStart to StreamEnd (see the tracker's doc for
//! what each state does):
//! * after a `restart`, Start (with `emit_start`: StreamStart, pushed once
//!   the record queue has `room`) or Done (the tracker only cleared);
//! * Run: the decide stage's end-of-row `step`s count the rows; the field's
//!   last row starts the walk at the end of the plane (Walk), whose last
//!   slot (`walked`) gives WalkEnd (the Dropped record), then plane t + 1;
//! * once t reaches `planes_total` with `stopping` (`finishing`), the
//!   stream end's `finish`, a walk unless t = 0, then Drain: the N drain
//!   planes, whose words the sequencer pops (`drain_pop`), each ended by a
//!   walk (DrainWalk) at its last flush row; after the last drain plane
//!   (t + 1 = `planes_total` + N, registered a clock ahead: t changes only
//!   at the end of a walk, and the drain walk that reads it ends at least
//!   M + 2 clocks later), Emit, a walk that emits the finished segments;
//! * End (StreamEnd, once the queue has `room`), then Done.
//!
//! A walk starts (`start_walk`) in the clock that enters its state.

use rust_hdl::prelude::*;

/// Tracker states.
#[derive(Copy, Clone, Debug, PartialEq, LogicState)]
pub enum TrackerState {
    /// No stream (the power-up state: nothing is pushed before a restart).
    Done,
    /// Push the StreamStart record.
    Start,
    /// Process the words of a plane.
    Run,
    /// End of plane, one slot per clock in slot order: deferred drop,
    /// cut, unconfirmed free or completion, the Blink record and its
    /// continuation, and the slot's state and ROI view for the next plane.
    Walk,
    /// End of plane: the Dropped record, then the next plane.
    WalkEnd,
    /// Stream end, one slot per clock: the model's `finish`.
    Finish,
    /// Follow the N drain planes.
    Drain,
    /// End of a drain plane, one slot per clock: ages and ROI view.
    DrainWalk,
    /// Emit the finished segments, slot order.
    Emit,
    /// Push StreamEnd.
    End,
}

/// The tracker's state, plane and rows. `NW`: bits of N.
#[derive(LogicBlock, Default)]
pub struct Sequencer<const NW: usize> {
    /// The clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: plane 0, no row done.
    pub restart: Signal<In, Bit>,
    /// With `restart`: a stream starts (Start); without, Done.
    pub emit_start: Signal<In, Bit>,
    /// N register.
    pub n_window: Signal<In, Bits<NW>>,
    /// No real plane after `planes_total` will come.
    pub stopping: Signal<In, Bit>,
    /// Number of real planes p of the stream (valid with `stopping`).
    pub planes_total: Signal<In, Bits<48>>,
    /// The record queue has room.
    pub room: Signal<In, Bit>,
    /// The decide stage ends a row of plane t.
    pub step: Signal<In, Bit>,
    /// … that row, the field's last.
    pub lastrow: Signal<In, Bit>,
    /// … that row's number.
    pub row: Signal<In, Bits<10>>,
    /// The walk's last slot is done this clock.
    pub walked: Signal<In, Bit>,
    /// A word is at the head of the input FIFO.
    pub in_valid: Signal<In, Bit>,
    /// It belongs to a flush or drain plane.
    pub in_flush: Signal<In, Bit>,
    /// Its row.
    pub in_y: Signal<In, Bits<16>>,
    /// It ends its row.
    pub head_eor: Signal<In, Bit>,
    /// Its row is the field's last.
    pub head_lastrow: Signal<In, Bit>,
    /// Plane t being tracked.
    pub t: Signal<Out, Bits<48>>,
    /// `t ≥ N`.
    pub t_ge_n: Signal<Out, Bit>,
    /// `t + 1 ≥ N`.
    pub t1_ge_n: Signal<Out, Bit>,
    /// Rows of plane t fully processed.
    pub rows: Signal<Out, Bits<16>>,
    /// The stream's last real plane is done: no word is decided now.
    pub finishing: Signal<Out, Bit>,
    /// A walk starts.
    pub start_walk: Signal<Out, Bit>,
    /// Pop the head word (a drain plane's).
    pub drain_pop: Signal<Out, Bit>,
    /// The state is Start.
    pub stream_start: Signal<Out, Bit>,
    /// … Run.
    pub run: Signal<Out, Bit>,
    /// … Walk.
    pub walk: Signal<Out, Bit>,
    /// … WalkEnd.
    pub walk_end: Signal<Out, Bit>,
    /// … Finish.
    pub finish: Signal<Out, Bit>,
    /// … DrainWalk.
    pub drain_walk: Signal<Out, Bit>,
    /// … Emit.
    pub emit: Signal<Out, Bit>,
    /// … End.
    pub stream_end: Signal<Out, Bit>,
    /// … Done.
    pub done: Signal<Out, Bit>,
    state: DFF<TrackerState>,
    t_r: DFF<Bits<48>>,
    rows_r: DFF<Bits<16>>,
    /// `t + 1 = planes_total + N` (the last drain plane), a clock old.
    drain_end: DFF<Bit>,
    t_p1: Signal<Local, Bits<48>>,
    n48: Signal<Local, Bits<48>>,
}

// Match guards do not translate to Verilog, so the ifs stay inside the arms.
#[allow(clippy::collapsible_match)]
impl<const NW: usize> Logic for Sequencer<NW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, state, t_r, rows_r, drain_end);
        self.n48.next = bit_cast::<48, NW>(self.n_window.val());
        self.t_p1.next = self.t_r.q.val() + 1;
        self.t_ge_n.next = self.t_r.q.val() >= self.n48.val();
        self.t1_ge_n.next = self.t_p1.val() >= self.n48.val();
        self.drain_end.d.next = self.t_p1.val() == (self.planes_total.val() + self.n48.val());
        self.finishing.next = self.stopping.val() & (self.t_r.q.val() == self.planes_total.val());
        self.start_walk.next = false;
        self.drain_pop.next = false;
        match self.state.q.val() {
            TrackerState::Start => {
                if self.room.val() {
                    self.state.d.next = TrackerState::Run;
                }
            }
            TrackerState::Run => {
                if self.finishing.val() {
                    self.start_walk.next = self.t_r.q.val() != 0;
                    self.state.d.next = TrackerState::Finish;
                } else if self.step.val() {
                    self.rows_r.d.next = bit_cast::<16, 10>(self.row.val()) + 1;
                    if self.lastrow.val() {
                        self.start_walk.next = true;
                        self.state.d.next = TrackerState::Walk;
                    }
                }
            }
            TrackerState::Walk => {
                if self.walked.val() {
                    self.state.d.next = TrackerState::WalkEnd;
                }
            }
            TrackerState::WalkEnd => {
                self.t_r.d.next = self.t_p1.val();
                self.rows_r.d.next = 0.into();
                self.state.d.next = TrackerState::Run;
            }
            TrackerState::Finish => {
                if self.t_r.q.val() == 0 {
                    self.state.d.next = TrackerState::End;
                } else if self.walked.val() {
                    self.state.d.next = TrackerState::Drain;
                }
            }
            TrackerState::Drain => {
                if self.in_valid.val() {
                    self.drain_pop.next = true;
                    if self.in_flush.val() & self.head_eor.val() {
                        self.rows_r.d.next = self.in_y.val() + 1;
                        if self.head_lastrow.val() {
                            self.start_walk.next = true;
                            self.state.d.next = TrackerState::DrainWalk;
                        }
                    }
                }
            }
            TrackerState::DrainWalk => {
                if self.walked.val() {
                    self.t_r.d.next = self.t_p1.val();
                    self.rows_r.d.next = 0.into();
                    self.state.d.next = TrackerState::Drain;
                    if self.drain_end.q.val() {
                        self.start_walk.next = true;
                        self.state.d.next = TrackerState::Emit;
                    }
                }
            }
            TrackerState::Emit => {
                if self.walked.val() {
                    self.state.d.next = TrackerState::End;
                }
            }
            TrackerState::End => {
                if self.room.val() {
                    self.state.d.next = TrackerState::Done;
                }
            }
            _ => {}
        }
        if self.restart.val() {
            self.state.d.next = TrackerState::Done;
            if self.emit_start.val() {
                self.state.d.next = TrackerState::Start;
            }
            self.t_r.d.next = 0.into();
            self.rows_r.d.next = 0.into();
        }
        self.t.next = self.t_r.q.val();
        self.rows.next = self.rows_r.q.val();
        self.stream_start.next = self.state.q.val() == TrackerState::Start;
        self.run.next = self.state.q.val() == TrackerState::Run;
        self.walk.next = self.state.q.val() == TrackerState::Walk;
        self.walk_end.next = self.state.q.val() == TrackerState::WalkEnd;
        self.finish.next = self.state.q.val() == TrackerState::Finish;
        self.drain_walk.next = self.state.q.val() == TrackerState::DrainWalk;
        self.emit.next = self.state.q.val() == TrackerState::Emit;
        self.stream_end.next = self.state.q.val() == TrackerState::End;
        self.done.next = self.state.q.val() == TrackerState::Done;
    }
}
