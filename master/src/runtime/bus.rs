//! What the cycle needs from a bus, so the engine does not care which one it drives.

use crate::ethercat::cycle::{CspCycle, CycleError};
use crate::ethercat::health::BusHealth;
use crate::ethercat::recovery::{Recovered, RecoveryError};

/// A bus as the cycle uses it. Every method runs in the cycle thread: no allocation, no
/// lock that the application could hold.
pub trait CycleBus {
    /// Decodes every axis' drive inputs into `cycle`; an axis whose drive the bus cannot
    /// reach (per `health`) gets a communication fault instead.
    fn read_inputs(&mut self, cycle: &mut CspCycle, health: &BusHealth) -> Result<(), CycleError>;
    /// Encodes every axis' outputs.
    fn write_outputs(&mut self, cycle: &mut CspCycle) -> Result<(), CycleError>;
    /// Sends the outputs and receives the inputs, waiting for them until `deadline_ns`
    /// (CLOCK_MONOTONIC) at most; records the outcome in `health` (no reply by then is a
    /// lost frame).
    fn exchange(&mut self, health: &mut BusHealth, deadline_ns: u64);
    /// Starts bringing the slave of `axis` back to OP if it left: from the next exchange
    /// on, each exchange also runs one register access of it (`ethercat::recovery`)
    /// under the same deadline, until it is back, refuses, or `timeout_ns` after `now_ns`
    /// passes. False (nothing started) while another recovery is running.
    fn start_recovery(&mut self, axis: usize, now_ns: u64, timeout_ns: u64) -> bool;
    /// The cycle is ready for the slaves to go to OP (in phase with SYNC0, where it locks
    /// to it): from the next exchange on, each asks one slave for OP beside the process
    /// data, until every slave was asked. The bus came up with its slaves in SafeOp.
    fn request_op(&mut self);
    /// A finished recovery: the axis that asked and the outcome (taken once).
    fn take_recovered(&mut self) -> Option<(usize, Result<Recovered, RecoveryError>)>;
    /// The chain position of `axis`' drive.
    fn drive_of(&self, axis: usize) -> usize;
    /// With distributed clocks: where in the SYNC0 period the last frame reached the
    /// reference clock (ns). `None` without DC.
    fn dc_offset_ns(&self) -> Option<u64> {
        None
    }
    /// Whether the last exchange measured [`CycleBus::dc_offset_ns`] afresh (a cycle
    /// may read something else in its place: the offset is then the one before, already
    /// corrected for).
    fn dc_measured(&self) -> bool {
        true
    }
}
