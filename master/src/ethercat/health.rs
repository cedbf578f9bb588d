//! Bus health: what each cycle's exchange said about the network, and what it means for
//! the axes. A lost frame or a wrong working counter is ridden through up to a limit (the
//! drives interpolate and their own watchdog is far longer than a few cycles); beyond it the
//! whole bus is faulted. A slave whose AL state is not OP — it stopped answering, or left
//! OP on its own — faults its own axes at once, and the others go on unless configured to
//! stop with it.
//!
//! Supervision, as IgH and SOEM do it: the LRW's working counter, every cycle. A slave that
//! stops answering (cable, power) no longer counts (ETG.1000.4 §5.4.3: +1 for a read, +2
//! for a write, per slave), so the cycle it goes is seen by its working counter; the
//! slaves' AL states are then read one by one in the next answered cycle, which names it
//! ([`BusHealth::reads_states`]). Until then nobody's inputs from that reply reach the
//! axes ([`BusHealth::inputs_fresh`]): which slave's bytes in it are stale is what the
//! states tell. A slave that leaves OP on its own (a sync error, a local error) may keep
//! its working counter right — its SyncManagers stay active in SafeOp, where it still
//! takes outputs and gives inputs (ETG.1000.6 §6.4.1) — so one cycle in
//! [`AL_STATUS_EVERY`] reads every slave's AL status ORed into one BRD (the bus sends it
//! instead of the DC time's FRMW, not beside it), and after a lost frame the states are
//! read (a drive that missed its setpoints leaves OP with a sync error, 0x10F1:02).
//!
//! At start the cycle itself takes the slaves from SafeOp to OP: bring-up only requests
//! OP, and the process data runs from the first cycle on, because a drive goes to OP only
//! with valid outputs and, once there, counts every SYNC0 period without a setpoint as a
//! sync error (two in a row take it out of OP again, ETG.1020 / 0x10F1:02). Until every
//! slave has reported OP — at most [`BusHealth::starting`]'s cycles — a slave still on its
//! way is no fault.

use ethercrab::SubDeviceState;
use thiserror::Error;

/// One answered cycle in this many reads every slave's AL status at once (one BRD of
/// 0x0130: each slave ORs its state in, ETG.1000.4 §5.4.1.2) when nothing else reads it,
/// to see a slave that left OP while its working counter stayed right: 100 ms at 1 ms.
pub const AL_STATUS_EVERY: u32 = 100;

/// How much trouble is ridden through.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HealthConfig {
    /// Frames lost in a row before the bus is faulted.
    pub lost_frames_limit: u32,
    /// Cycles in a row with a wrong working counter before the bus is faulted.
    pub working_counter_limit: u32,
    /// A slave that leaves OP faults every axis, not only its own.
    pub stop_all_on_slave_loss: bool,
}

impl Default for HealthConfig {
    fn default() -> Self {
        Self {
            lost_frames_limit: 3,
            working_counter_limit: 3,
            stop_all_on_slave_loss: false,
        }
    }
}

/// What a slave did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlaveProblem {
    /// Its AL status read came back unanswered.
    NoAnswer,
    /// It answered from another state.
    LeftOp(SubDeviceState),
    /// At start it did not reach OP in time.
    NotInOp {
        /// Its state when time ran out.
        state: SubDeviceState,
        /// The time it had (ms).
        waited_ms: u64,
    },
}

impl std::fmt::Display for SlaveProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SlaveProblem::NoAnswer => f.write_str("does not answer (cable, power?)"),
            SlaveProblem::LeftOp(state) => write!(f, "left OP: now {state}"),
            SlaveProblem::NotInOp { state, waited_ms } => {
                write!(f, "did not reach OP in {waited_ms} ms: still {state}")
            }
        }
    }
}

/// Why axes were stopped. `Copy`, so the RT thread records it without allocating.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum BusFault {
    /// Frames did not come back.
    #[error("EtherCAT: {count} frames lost in a row (limit {limit})")]
    FramesLost {
        /// Lost in a row.
        count: u32,
        /// The configured limit.
        limit: u32,
    },
    /// The working counter was wrong.
    #[error(
        "EtherCAT: working counter {got} instead of {expected} for {count} cycles in a row (limit {limit})"
    )]
    WorkingCounter {
        /// Expected value.
        expected: u16,
        /// Last value seen.
        got: u16,
        /// Cycles in a row.
        count: u32,
        /// The configured limit.
        limit: u32,
    },
    /// A slave is not in OP.
    #[error("EtherCAT: slave {position} ({address:#06x}) {problem}")]
    Slave {
        /// Position in the chain.
        position: usize,
        /// Station address.
        address: u16,
        /// What it did.
        problem: SlaveProblem,
    },
    /// Another slave left OP and the configuration stops every axis with it.
    #[error("EtherCAT: stopped with slave {position} ({address:#06x})")]
    WithSlave {
        /// Position of the slave that was lost.
        position: usize,
        /// Its station address.
        address: u16,
    },
}

/// One cycle's exchange as the master saw it.
#[derive(Clone, Copy, Debug)]
pub enum Exchange<'a> {
    /// The frame did not come back in time.
    Lost,
    /// It came back with this working counter and what it read of the AL states.
    Answered {
        /// Working counter of the process data.
        working_counter: u16,
        /// The slaves' AL states as this cycle read them.
        states: States<'a>,
    },
}

/// What a cycle read of the slaves' AL states beside the process data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum States<'a> {
    /// Nothing (the steady cycle: the working counter supervises).
    NotRead,
    /// Every slave's AL status ORed into one BRD: whether every slave answered it and the
    /// result is OP without the error flag.
    Summary {
        /// Every slave in OP, no error.
        all_in_op: bool,
    },
    /// Each slave's state, in chain order (`None`: it did not answer).
    Each(&'a [SubDeviceState]),
}

/// Counters and verdicts.
#[derive(Clone, Debug)]
pub struct BusHealth {
    config: HealthConfig,
    expected_wkc: u16,
    /// What each slave adds to the working counter when it exchanges.
    slave_wkc: Vec<u16>,
    addresses: Vec<u16>,
    lost_run: u32,
    wkc_run: u32,
    /// Frames lost since start.
    pub lost_total: u64,
    /// Cycles with a wrong working counter since start that no lost slave explains.
    pub wkc_total: u64,
    bus: Option<BusFault>,
    slaves: Vec<Option<BusFault>>,
    /// While the slaves are on their way to OP: answered cycles left, and the time they
    /// get in all (ms, for the message).
    starting: Option<(u32, u64)>,
    /// A cycle's working counter was wrong and the states were not read with it: it is
    /// judged when they are (a slave that is gone explains it; else it counts).
    unjudged_wkc: bool,
    /// The AL-status summary said a slave is not in OP: read each one's state.
    check_states: bool,
    /// Answered cycles since the AL states (each, or the summary) were last read.
    since_al_read: u32,
    /// Per slave: its inputs in the image came with the last exchange.
    fresh: Vec<bool>,
}

impl BusHealth {
    /// Health of a bus whose slaves have these station addresses and add these counts to
    /// the process data's working counter when they exchange (`slave_wkc`, in chain order:
    /// ETG.1000.4 §5.4.3, per LRW datagram 1 for inputs, 2 for outputs).
    pub fn new(config: HealthConfig, addresses: Vec<u16>, slave_wkc: Vec<u16>) -> Self {
        let n = addresses.len();
        Self {
            config,
            expected_wkc: slave_wkc.iter().sum(),
            slave_wkc,
            addresses,
            lost_run: 0,
            wkc_run: 0,
            lost_total: 0,
            wkc_total: 0,
            bus: None,
            slaves: vec![None; n],
            starting: None,
            unjudged_wkc: false,
            check_states: false,
            since_al_read: 0,
            fresh: vec![false; n],
        }
    }

    /// The slaves have been asked for OP and get `cycles` answered cycles (`waited_ms` of
    /// time) to report it; until then a slave in another state is on its way, not lost.
    pub fn starting(mut self, cycles: u32, waited_ms: u64) -> Self {
        self.starting = Some((cycles, waited_ms));
        self
    }

    /// The working counter a cycle's process data comes back with when every slave
    /// exchanged.
    pub fn expected_working_counter(&self) -> u16 {
        self.expected_wkc
    }

    /// Whether the next cycle reads every slave's AL state beside the process data: while
    /// the slaves are on their way to OP, after a cycle whose working counter was wrong,
    /// when the AL-status summary saw a slave out of OP, and while anything is wrong (a
    /// slave out of OP, a bus fault) until a reset clears it. After a lost frame the
    /// summary comes first ([`BusHealth::reads_summary`]): reading each state makes the
    /// cycle after a host stall heavier, and on a host without real time that made one
    /// lost frame three in a row (over veth: 17 of 50 runs stopped, 4 failed; with the
    /// summary first 9 of 50 stopped once, none failed).
    /// Otherwise the cycle sends the process data alone, the working counter supervising
    /// (as IgH and SOEM do), but for the summary now and then ([`BusHealth::reads_summary`]).
    pub fn reads_states(&self) -> bool {
        self.starting.is_some()
            || self.wkc_run > 0
            || self.unjudged_wkc
            || self.check_states
            || self.any_fault()
    }

    /// Whether the next cycle reads every slave's AL status in one BRD (every
    /// [`AL_STATUS_EVERY`] answered cycles, and after a lost frame — drives that missed
    /// setpoints may have left OP with a sync error —, when it does not read each state).
    pub fn reads_summary(&self) -> bool {
        !self.reads_states() && (self.lost_run > 0 || self.since_al_read + 1 >= AL_STATUS_EVERY)
    }

    /// Whether slave `i`'s inputs came with the last exchange: it was answered, and its
    /// working counter was right or the slaves that did not answer (named by the states read
    /// with it) account for exactly what it lacked. False after a wrong working counter
    /// whose cause the states have not yet told: the image then holds stale bytes of some
    /// slaves, and which is not known.
    pub fn inputs_fresh(&self, i: usize) -> bool {
        self.fresh.get(i).copied().unwrap_or(false)
    }

    /// Whether the slaves are still on their way to OP.
    pub fn is_starting(&self) -> bool {
        self.starting.is_some()
    }

    /// Takes one cycle's outcome.
    pub fn record(&mut self, exchange: Exchange<'_>) {
        match exchange {
            Exchange::Lost => {
                self.fresh.iter_mut().for_each(|f| *f = false);
                self.lost_total += 1;
                self.lost_run += 1;
                if self.lost_run >= self.config.lost_frames_limit && self.bus.is_none() {
                    self.bus = Some(BusFault::FramesLost {
                        count: self.lost_run,
                        limit: self.config.lost_frames_limit,
                    });
                }
            }
            Exchange::Answered {
                working_counter,
                states,
            } => {
                self.lost_run = 0;
                match states {
                    States::NotRead => self.since_al_read = self.since_al_read.saturating_add(1),
                    States::Summary { all_in_op } => {
                        self.since_al_read = 0;
                        self.check_states |= !all_in_op;
                    }
                    States::Each(_) => {
                        self.since_al_read = 0;
                        self.check_states = false;
                    }
                }
                let States::Each(states) = states else {
                    // The working counter alone: right, every slave's inputs came; wrong,
                    // judged with the states next cycle, nobody's inputs taken meanwhile.
                    let right = working_counter == self.expected_wkc;
                    self.fresh.iter_mut().for_each(|f| *f = right);
                    if right {
                        self.wkc_run = 0;
                    } else {
                        self.unjudged_wkc = true;
                    }
                    return;
                };
                if let Some((left, waited_ms)) = self.starting {
                    let answering = !states.contains(&SubDeviceState::None);
                    if states.iter().all(|s| *s == SubDeviceState::Op) {
                        self.starting = None;
                    } else if answering && left > 0 {
                        self.starting = Some((left - 1, waited_ms));
                        // On their way, the slaves' counts are no verdict yet.
                        self.judge_working_counter(working_counter, states, false);
                        return;
                    } else if answering {
                        self.starting = None;
                        self.not_in_op(states, waited_ms);
                    } else {
                        // A slave that does not answer is lost at once, starting or not.
                        self.starting = None;
                    }
                }
                let mut lost_slave = None;
                for (i, state) in states.iter().enumerate() {
                    if *state != SubDeviceState::Op {
                        if let Some(slot) = self.slaves.get_mut(i) {
                            if slot.is_none() {
                                *slot = Some(BusFault::Slave {
                                    position: i,
                                    address: self.addresses.get(i).copied().unwrap_or(0),
                                    problem: match state {
                                        SubDeviceState::None => SlaveProblem::NoAnswer,
                                        other => SlaveProblem::LeftOp(*other),
                                    },
                                });
                            }
                        }
                        lost_slave.get_or_insert(i);
                    }
                }
                self.judge_working_counter(working_counter, states, true);
                if let (Some(i), true, None) =
                    (lost_slave, self.config.stop_all_on_slave_loss, &self.bus)
                {
                    self.bus = Some(BusFault::WithSlave {
                        position: i,
                        address: self.addresses.get(i).copied().unwrap_or(0),
                    });
                }
            }
        }
    }

    /// A working counter read with every slave's state: right when it is what the slaves
    /// that answered add up to (a slave that is gone explains what it lacks; one that
    /// answered from SafeOp still exchanges, ETG.1000.6 §6.4.1). Then the inputs of those
    /// that answered are fresh. Otherwise it counts towards the limit — with the cycle
    /// before, if that one's was wrong too and waited for these states — and no slave's
    /// inputs are taken. While the slaves are on their way to OP (`count` false) nothing
    /// counts.
    fn judge_working_counter(
        &mut self,
        working_counter: u16,
        states: &[SubDeviceState],
        count: bool,
    ) {
        let gone: u16 = states
            .iter()
            .zip(&self.slave_wkc)
            .filter(|(s, _)| **s == SubDeviceState::None)
            .map(|(_, w)| *w)
            .sum();
        let explained = working_counter == self.expected_wkc.saturating_sub(gone);
        for (i, fresh) in self.fresh.iter_mut().enumerate() {
            *fresh = explained && states.get(i).is_some_and(|s| *s != SubDeviceState::None);
        }
        let unjudged = std::mem::take(&mut self.unjudged_wkc);
        if explained || !count {
            self.wkc_run = 0;
            return;
        }
        let cycles = 1 + u32::from(unjudged);
        self.wkc_total += u64::from(cycles);
        self.wkc_run += cycles;
        if self.wkc_run >= self.config.working_counter_limit && self.bus.is_none() {
            self.bus = Some(BusFault::WorkingCounter {
                expected: self.expected_wkc,
                got: working_counter,
                count: self.wkc_run,
                limit: self.config.working_counter_limit,
            });
        }
    }

    /// Time ran out at start: every slave not in OP faults its axes with its state.
    fn not_in_op(&mut self, states: &[SubDeviceState], waited_ms: u64) {
        for (i, state) in states.iter().enumerate() {
            if *state == SubDeviceState::Op {
                continue;
            }
            if let Some(slot) = self.slaves.get_mut(i) {
                slot.get_or_insert(BusFault::Slave {
                    position: i,
                    address: self.addresses.get(i).copied().unwrap_or(0),
                    problem: SlaveProblem::NotInOp {
                        state: *state,
                        waited_ms,
                    },
                });
            }
        }
    }

    /// Why slave `i`'s axes must stop, if they must.
    pub fn fault(&self, i: usize) -> Option<BusFault> {
        self.slaves.get(i).copied().flatten().or(self.bus)
    }

    /// Whether any fault is in force.
    pub fn any_fault(&self) -> bool {
        self.bus.is_some() || self.slaves.iter().any(Option::is_some)
    }

    /// Forgets the faults once the slaves are back (after a reset). The next cycle reads
    /// every slave's state, so that a fault still there is back at once.
    pub fn clear(&mut self) {
        self.check_states = true;
        self.bus = None;
        self.lost_run = 0;
        self.wkc_run = 0;
        self.unjudged_wkc = false;
        self.slaves.iter_mut().for_each(|s| *s = None);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use SubDeviceState::{Op, SafeOp};

    fn health() -> BusHealth {
        BusHealth::new(HealthConfig::default(), vec![0x1000, 0x1001], vec![3, 3])
    }

    #[test]
    fn lost_frames_are_ridden_through_up_to_the_limit() {
        let mut h = health();
        let ok = Exchange::Answered {
            working_counter: 6,
            states: States::Each(&[Op, Op]),
        };
        for _ in 0..2 {
            h.record(Exchange::Lost);
        }
        h.record(ok);
        h.record(Exchange::Lost);
        h.record(Exchange::Lost);
        assert_eq!(h.fault(0), None, "never three in a row");
        h.record(Exchange::Lost);
        assert_eq!(
            h.fault(1).unwrap().to_string(),
            "EtherCAT: 3 frames lost in a row (limit 3)"
        );
        assert_eq!(h.lost_total, 5);
        h.clear();
        assert_eq!(h.fault(0), None);
    }

    #[test]
    fn wrong_working_counters_count_unless_a_slave_that_is_gone_explains_them() {
        let mut h = health();
        for _ in 0..3 {
            h.record(Exchange::Answered {
                working_counter: 4,
                states: States::Each(&[Op, Op]),
            });
        }
        assert!(matches!(
            h.fault(0),
            Some(BusFault::WorkingCounter { got: 4, .. })
        ));
        let mut h = health();
        h.record(Exchange::Answered {
            working_counter: 3,
            states: States::Each(&[Op, SubDeviceState::None]),
        });
        assert_eq!(h.fault(0), None, "the other slave goes on");
        assert_eq!(
            h.fault(1).unwrap().to_string(),
            "EtherCAT: slave 1 (0x1001) does not answer (cable, power?)"
        );
        assert_eq!(h.wkc_total, 0);
    }

    #[test]
    fn slaves_on_their_way_to_op_at_start_are_no_fault_until_time_runs_out() {
        let start = || health().starting(3, 3);
        let answered = |h: &mut BusHealth, states: &[SubDeviceState]| {
            h.record(Exchange::Answered {
                working_counter: 6,
                states: States::Each(states),
            })
        };
        // Both reach OP in time: no fault, and from then on leaving OP is one.
        let mut h = start();
        answered(&mut h, &[SafeOp, SafeOp]);
        answered(&mut h, &[Op, SafeOp]);
        assert!(h.is_starting() && !h.any_fault());
        answered(&mut h, &[Op, Op]);
        assert!(!h.is_starting() && !h.any_fault());
        answered(&mut h, &[Op, SafeOp]);
        assert!(h.fault(1).unwrap().to_string().contains("left OP: now"));
        // One never gets there: after 3 answered cycles it faults with its state.
        let mut h = start();
        for _ in 0..3 {
            answered(&mut h, &[Op, SafeOp]);
        }
        assert!(!h.any_fault());
        answered(&mut h, &[Op, SafeOp]);
        assert_eq!(h.fault(0), None);
        assert_eq!(
            h.fault(1).unwrap().to_string(),
            "EtherCAT: slave 1 (0x1001) did not reach OP in 3 ms: still Safe-Operational"
        );
        // A slave that does not answer is lost at once.
        let mut h = start();
        answered(&mut h, &[SafeOp, SubDeviceState::None]);
        assert!(h.fault(1).unwrap().to_string().contains("does not answer"));
    }

    #[test]
    fn a_lost_slave_can_stop_everything() {
        let config = HealthConfig {
            stop_all_on_slave_loss: true,
            ..HealthConfig::default()
        };
        let mut h = BusHealth::new(config, vec![0x1000, 0x1001], vec![3, 3]);
        h.record(Exchange::Answered {
            working_counter: 6,
            states: States::Each(&[SafeOp, Op]),
        });
        assert!(h.fault(0).unwrap().to_string().contains("left OP: now"));
        assert_eq!(
            h.fault(1).unwrap().to_string(),
            "EtherCAT: stopped with slave 0 (0x1000)"
        );
    }

    /// The pulled cable as the cycle sees it: the working counter drops in the cycle the
    /// slave goes (nobody's inputs taken, no verdict yet), the next cycle reads the states
    /// and names it; its count explained, no working-counter error is counted, and the
    /// other slave's inputs are fresh again.
    #[test]
    fn a_wrong_working_counter_is_judged_with_the_states_read_next_cycle() {
        let mut h = health();
        let steady = |working_counter| Exchange::Answered {
            working_counter,
            states: States::NotRead,
        };
        h.record(steady(6));
        assert!(!h.reads_states() && h.inputs_fresh(0) && h.inputs_fresh(1));
        h.record(steady(3));
        assert!(h.reads_states(), "the states are read next cycle");
        assert!(
            !h.inputs_fresh(0) && !h.inputs_fresh(1),
            "whose bytes are stale?"
        );
        assert!(!h.any_fault());
        h.record(Exchange::Answered {
            working_counter: 3,
            states: States::Each(&[Op, SubDeviceState::None]),
        });
        assert_eq!(
            h.fault(1).unwrap().to_string(),
            "EtherCAT: slave 1 (0x1001) does not answer (cable, power?)"
        );
        assert_eq!(h.fault(0), None);
        assert!(h.inputs_fresh(0) && !h.inputs_fresh(1));
        assert_eq!(h.wkc_total, 0, "explained by the slave that is gone");
        // A count short of what the gone slave explains is a working-counter error, and
        // it takes the unjudged cycle before with it.
        let mut h = health();
        h.record(steady(1));
        h.record(Exchange::Answered {
            working_counter: 1,
            states: States::Each(&[Op, SubDeviceState::None]),
        });
        assert_eq!(h.wkc_total, 2);
        assert!(!h.inputs_fresh(0), "slave 0 did not exchange either");
        // With every slave in OP and the count wrong, the third cycle faults the bus, as
        // when the states were read every cycle.
        let mut h = health();
        h.record(steady(3));
        h.record(Exchange::Answered {
            working_counter: 3,
            states: States::Each(&[Op, Op]),
        });
        assert!(!h.any_fault());
        h.record(Exchange::Answered {
            working_counter: 3,
            states: States::Each(&[Op, Op]),
        });
        assert_eq!(
            h.fault(0).unwrap().to_string(),
            "EtherCAT: working counter 3 instead of 6 for 3 cycles in a row (limit 3)"
        );
    }

    /// A slave that left OP with its working counter right is seen by the AL-status
    /// summary, read one cycle in [`AL_STATUS_EVERY`]; its state is read the cycle after.
    /// After a lost frame the states are read at once.
    #[test]
    fn the_summary_is_read_now_and_then_and_the_states_when_it_says_so() {
        let mut h = health();
        let steady = Exchange::Answered {
            working_counter: 6,
            states: States::NotRead,
        };
        let mut summaries = Vec::new();
        for cycle in 0..3 * AL_STATUS_EVERY {
            if h.reads_summary() {
                summaries.push(cycle);
                h.record(Exchange::Answered {
                    working_counter: 6,
                    states: States::Summary { all_in_op: true },
                });
            } else {
                assert!(!h.reads_states());
                h.record(steady);
            }
        }
        let every = AL_STATUS_EVERY;
        assert_eq!(summaries, [every - 1, 2 * every - 1, 3 * every - 1]);
        h.record(Exchange::Answered {
            working_counter: 6,
            states: States::Summary { all_in_op: false },
        });
        assert!(h.reads_states() && !h.reads_summary());
        assert!(h.inputs_fresh(1), "the working counter was right");
        h.record(Exchange::Answered {
            working_counter: 6,
            states: States::Each(&[Op, SafeOp]),
        });
        assert_eq!(
            h.fault(1).unwrap().to_string(),
            "EtherCAT: slave 1 (0x1001) left OP: now Safe-Operational"
        );
        assert_eq!(h.wkc_total, 0);
        // A lost frame: nobody's inputs came; the next cycle reads the summary (not each
        // state: a cycle right after a host stall stays as light as the others), and each
        // state only if the summary saw a slave out of OP.
        let mut h = health();
        h.record(Exchange::Lost);
        assert!(!h.reads_states() && h.reads_summary() && !h.inputs_fresh(0));
        h.record(Exchange::Answered {
            working_counter: 6,
            states: States::Summary { all_in_op: true },
        });
        assert!(!h.reads_states() && !h.reads_summary());
        assert!(h.inputs_fresh(0) && h.inputs_fresh(1));
        h.record(Exchange::Lost);
        h.record(Exchange::Answered {
            working_counter: 6,
            states: States::Summary { all_in_op: false },
        });
        assert!(h.reads_states(), "the summary saw a slave out of OP");
    }
}
