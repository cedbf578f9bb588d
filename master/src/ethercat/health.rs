//! Bus health: what each cycle's exchange said about the network, and what it means for
//! the axes. A lost frame or a wrong working counter is ridden through up to a limit (the
//! drives interpolate and their own watchdog is far longer than a few cycles); beyond it the
//! whole bus is faulted. A slave whose AL state is not OP — it stopped answering, or left
//! OP on its own — faults its own axes at once, and the others go on unless configured to
//! stop with it.
//!
//! At start the cycle itself takes the slaves from SafeOp to OP: bring-up only requests
//! OP, and the process data runs from the first cycle on, because a drive goes to OP only
//! with valid outputs and, once there, counts every SYNC0 period without a setpoint as a
//! sync error (two in a row take it out of OP again, ETG.1020 / 0x10F1:02). Until every
//! slave has reported OP — at most [`BusHealth::starting`]'s cycles — a slave still on its
//! way is no fault.

use ethercrab::SubDeviceState;
use thiserror::Error;

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
    /// It came back with this working counter and these AL states (one per slave).
    Answered {
        /// Working counter of the process data.
        working_counter: u16,
        /// AL state of every slave, in order; empty when they were not read this cycle
        /// (the cyclic frame reads them only when the working counter is wrong, and at
        /// start).
        states: &'a [SubDeviceState],
    },
}

/// Counters and verdicts.
#[derive(Clone, Debug)]
pub struct BusHealth {
    config: HealthConfig,
    expected_wkc: u16,
    addresses: Vec<u16>,
    lost_run: u32,
    wkc_run: u32,
    /// Frames lost since start.
    pub lost_total: u64,
    /// Cycles with a wrong working counter since start.
    pub wkc_total: u64,
    bus: Option<BusFault>,
    slaves: Vec<Option<BusFault>>,
    /// While the slaves are on their way to OP: answered cycles left, and the time they
    /// get in all (ms, for the message).
    starting: Option<(u32, u64)>,
}

impl BusHealth {
    /// Health of a bus whose slaves have these station addresses and whose process data
    /// should come back with `expected_wkc`.
    pub fn new(config: HealthConfig, addresses: Vec<u16>, expected_wkc: u16) -> Self {
        let n = addresses.len();
        Self {
            config,
            expected_wkc,
            addresses,
            lost_run: 0,
            wkc_run: 0,
            lost_total: 0,
            wkc_total: 0,
            bus: None,
            slaves: vec![None; n],
            starting: None,
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
    /// the slaves are on their way to OP, and while anything is wrong (a slave out of OP,
    /// a wrong working counter, a bus fault) until a reset clears it. Otherwise the cycle
    /// sends the process data alone and reads the states only in a cycle whose working
    /// counter is wrong (as IgH and SOEM supervise).
    pub fn reads_states(&self) -> bool {
        self.starting.is_some() || self.wkc_run > 0 || self.any_fault()
    }

    /// Whether the slaves are still on their way to OP.
    pub fn is_starting(&self) -> bool {
        self.starting.is_some()
    }

    /// Takes one cycle's outcome.
    pub fn record(&mut self, exchange: Exchange<'_>) {
        match exchange {
            Exchange::Lost => {
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
                if self.starting.is_some() && states.is_empty() {
                    // Starting, the states are what tell: none this cycle, no news.
                    return;
                }
                if let Some((left, waited_ms)) = self.starting {
                    let answering = !states.contains(&SubDeviceState::None);
                    if states.iter().all(|s| *s == SubDeviceState::Op) {
                        self.starting = None;
                    } else if answering && left > 0 {
                        self.starting = Some((left - 1, waited_ms));
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
                // A slave that is gone explains the working counter; count it only when
                // every slave says it is in OP (or the states were not read).
                if working_counter != self.expected_wkc && lost_slave.is_none() {
                    self.wkc_total += 1;
                    self.wkc_run += 1;
                    if self.wkc_run >= self.config.working_counter_limit && self.bus.is_none() {
                        self.bus = Some(BusFault::WorkingCounter {
                            expected: self.expected_wkc,
                            got: working_counter,
                            count: self.wkc_run,
                            limit: self.config.working_counter_limit,
                        });
                    }
                } else {
                    self.wkc_run = 0;
                }
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

    /// Forgets the faults once the slaves are back (after a reset).
    pub fn clear(&mut self) {
        self.bus = None;
        self.lost_run = 0;
        self.wkc_run = 0;
        self.slaves.iter_mut().for_each(|s| *s = None);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use SubDeviceState::{Op, SafeOp};

    fn health() -> BusHealth {
        BusHealth::new(HealthConfig::default(), vec![0x1000, 0x1001], 6)
    }

    #[test]
    fn lost_frames_are_ridden_through_up_to_the_limit() {
        let mut h = health();
        let ok = Exchange::Answered {
            working_counter: 6,
            states: &[Op, Op],
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
    fn wrong_working_counters_count_only_while_all_slaves_are_in_op() {
        let mut h = health();
        for _ in 0..3 {
            h.record(Exchange::Answered {
                working_counter: 4,
                states: &[Op, Op],
            });
        }
        assert!(matches!(
            h.fault(0),
            Some(BusFault::WorkingCounter { got: 4, .. })
        ));
        let mut h = health();
        h.record(Exchange::Answered {
            working_counter: 3,
            states: &[Op, SubDeviceState::None],
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
                working_counter: 1,
                states,
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
        let mut h = BusHealth::new(config, vec![0x1000, 0x1001], 6);
        h.record(Exchange::Answered {
            working_counter: 6,
            states: &[SafeOp, Op],
        });
        assert!(h.fault(0).unwrap().to_string().contains("left OP: now"));
        assert_eq!(
            h.fault(1).unwrap().to_string(),
            "EtherCAT: stopped with slave 0 (0x1000)"
        );
    }
}
