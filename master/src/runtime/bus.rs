//! What the cycle needs from a bus, so the engine does not care which one it drives: it
//! moves each drive's process data bytes, says which drives it cannot reach and why, and
//! brings a drive back when a reset asks for it. The EtherCAT bus is one
//! implementation; every bus-specific notion (AL states, working counters, SII) stays in
//! it, behind the text of [`Unreachable`] and the kernel's [`CommandError`].

use std::fmt;

use gantry_kernel::axis::command::CommandError;

use super::sdo::{SdoBuffer, SdoEnded, SdoError, SdoTransfer};

/// A bus as the cycle uses it. Drives are named by their position on the bus (what an
/// axis' `drive` says in the configuration). Every method runs in the cycle thread: no
/// allocation, no lock that the application could hold.
pub trait CycleBus {
    /// Positions on the bus (`0..drives()`), drives or not.
    fn drives(&self) -> usize;
    /// Drive `drive`'s input bytes as the last exchange left them (empty if there is no
    /// such drive).
    fn inputs(&self, drive: usize) -> &[u8];
    /// Drive `drive`'s output bytes as the next exchange sends them (empty if there is no
    /// such drive).
    fn outputs(&self, drive: usize) -> &[u8];
    /// Drive `drive`'s output bytes, to write (empty if there is no such drive).
    fn outputs_mut(&mut self, drive: usize) -> &mut [u8];
    /// Sends the outputs and receives the inputs, waiting for them until `deadline_ns`
    /// (CLOCK_MONOTONIC) at most (no reply by then is a lost exchange); the bus judges
    /// its health from what came back ([`CycleBus::fault`]).
    fn exchange(&mut self, deadline_ns: u64) -> Reply;
    /// Why the cycle cannot reach drive `drive`, if it cannot: its axes get a
    /// communication fault instead of its inputs.
    fn fault(&self, drive: usize) -> Option<&Unreachable>;
    /// Whether drive `drive`'s inputs came with the last exchange. A bus that cannot tell
    /// yet whose bytes in a reply are stale (EtherCAT: a wrong working counter, judged with
    /// the slaves' states read next cycle) or got no reply says no: the cycle then decodes
    /// none, its axes keep what they had.
    fn inputs_fresh(&self, drive: usize) -> bool {
        let _ = drive;
        true
    }
    /// The error drive `drive` reported outside its process data (CANopen: its EMCY),
    /// while in force (until the drive reports it gone). Without such a channel (EtherCAT
    /// drives report through 0x603F in the process data): none.
    fn drive_error(&self, drive: usize) -> Option<DriveError> {
        let _ = drive;
        None
    }
    /// Whether any drive cannot be reached.
    fn any_fault(&self) -> bool;
    /// Forgets the faults once a drive is back (after a reset); they return with the next
    /// exchange if their cause is still there.
    fn clear_faults(&mut self);
    /// Exchanges lost and answered incomplete since start.
    fn counters(&self) -> BusCounters;
    /// The cycle is ready for the drives to go operational (in phase with the bus' clock,
    /// where it locks to it): from the next exchange on the bus takes them there beside
    /// the process data. The bus came up with the process data running and the drives
    /// not yet operational.
    fn start_operation(&mut self);
    /// Starts bringing drive `drive` back to operation if it left (a reset): from the
    /// next exchange on, each exchange does one step of it under the same deadline, until
    /// it is back, refuses, or `timeout_ns` after `now_ns` passes. False (nothing
    /// started) while another one is running.
    fn start_restore(&mut self, drive: usize, now_ns: u64, timeout_ns: u64) -> bool;
    /// How the last restore ended, once it has (taken once).
    fn take_restored(&mut self) -> Option<Result<Restored, CommandError>>;
    /// How long a drive may take to come back before its reset fails (ns).
    fn restore_timeout_ns(&self) -> u64;
    /// With a clock shared with the drives (EtherCAT's distributed clocks): where in the
    /// drives' sync period the last exchange reached it (ns). `None` without one.
    fn dc_offset_ns(&self) -> Option<u64> {
        None
    }
    /// Whether the last exchange measured [`CycleBus::dc_offset_ns`] afresh (a cycle
    /// may read something else in its place: the offset is then the one before, already
    /// corrected for).
    fn dc_measured(&self) -> bool {
        true
    }
    /// Starts an SDO transfer beside the process data, its bytes in `buffer` (a
    /// download's data; an upload's place, its capacity the largest object taken): from
    /// the next exchange on, each exchange does a bounded step of it under the same
    /// deadline, never delaying the process data, until it ends or the drive stays silent
    /// for `transfer.timeout_ns`; its outcome and the buffer come back from
    /// [`CycleBus::take_sdo`]. Refused at once, the buffer handed back
    /// ([`SdoEnded::refused`]): [`SdoError::Busy`] while another transfer runs, or what
    /// the bus cannot do — by default, [`SdoError::NotSupported`]. The buffer is never
    /// grown nor freed here.
    fn start_sdo(
        &mut self,
        transfer: &SdoTransfer,
        buffer: SdoBuffer,
        now_ns: u64,
    ) -> Result<(), SdoEnded> {
        let _ = (transfer, now_ns);
        Err(SdoEnded::refused(SdoError::NotSupported, buffer))
    }
    /// How the transfer started last ended, once it has (taken once), with its buffer:
    /// the object's bytes after an upload, none after a download.
    fn take_sdo(&mut self) -> Option<SdoEnded> {
        None
    }
    /// On CANopen: what the bus knows of drive `drive`'s node (its id, the NMT state its
    /// heartbeat reports, lost TPDOs), for the status. `None` on other buses.
    fn can_node(&self, drive: usize) -> Option<CanNodeStatus> {
        let _ = drive;
        None
    }
}

/// A CANopen drive's node as the bus sees it (`gantry status`). `Copy`: it crosses the
/// cycle thread in the snapshot without allocating.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CanNodeStatus {
    /// Node id.
    pub node: u8,
    /// The NMT state its last heartbeat reported (CiA 301 §7.2.8.3.2); `None` before the
    /// first one.
    pub nmt: Option<&'static str>,
    /// Time since its last heartbeat (or since the bus came up), at the last exchange (ms).
    pub heard_ms_ago: u64,
    /// Heartbeat consumer time: silence this long stops its axes (ms; 0: not watched).
    pub heartbeat_limit_ms: u64,
    /// Exchanges whose TPDOs from it were missing (lost or late), since start.
    pub lost_tpdos: u64,
    /// Of which in a row, up to the last exchange.
    pub lost_in_a_row: u32,
}

/// An error a drive reported outside its process data ([`CycleBus::drive_error`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DriveError {
    /// The error code (CiA 301 / CiA 402 emergency code: the drive's 0x603F for its
    /// faults).
    pub code: u16,
    /// It came with the last exchange: a new error, which stops the axis whether or not
    /// the drive faulted (the cycle gives it to the kernel as the drive's fault once).
    pub fresh: bool,
}

/// How an exchange went.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reply {
    /// The reply came back in time (complete or not: see [`CycleBus::fault`]).
    Answered,
    /// No reply by the deadline, or nothing could be sent.
    Lost,
}

/// What a restore did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Restored {
    /// The drive was operational already.
    WasOperational,
    /// Its error was acknowledged and it is operational again.
    BackInOperation,
}

/// The bus' counters since start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusCounters {
    /// Exchanges whose reply did not come back in time.
    pub lost: u64,
    /// Exchanges answered incomplete (on EtherCAT: a wrong working counter).
    pub incomplete: u64,
}

/// Room for the text of a reason (the longest EtherCAT one is about 100 bytes).
const REASON_BYTES: usize = 160;

/// Why the cycle cannot reach a drive: the bus' own reason, as it displays it. `Copy` and
/// fixed-size, so the cycle thread hands it to the application without allocating; the
/// bus makes it once, when the fault arises.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Unreachable {
    len: u8,
    text: [u8; REASON_BYTES],
}

impl Unreachable {
    /// The reason `reason` displays (without allocating; a text longer than
    /// 160 bytes is cut at a character boundary).
    pub fn new(reason: &impl fmt::Display) -> Self {
        let mut text = Text {
            len: 0,
            bytes: [0; REASON_BYTES],
        };
        // `Text` never fails: it drops what does not fit.
        let _ = fmt::write(&mut text, format_args!("{reason}"));
        Self {
            len: text.len as u8,
            text: text.bytes,
        }
    }

    /// The reason.
    pub fn reason(&self) -> &str {
        let bytes = self.text.get(..usize::from(self.len)).unwrap_or_default();
        // Only whole characters were copied in (see `Text`).
        std::str::from_utf8(bytes).unwrap_or_default()
    }
}

impl fmt::Display for Unreachable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.reason())
    }
}

impl fmt::Debug for Unreachable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("Unreachable").field(&self.reason()).finish()
    }
}

impl std::error::Error for Unreachable {}

/// A fixed buffer that takes whole characters while they fit.
struct Text {
    len: usize,
    bytes: [u8; REASON_BYTES],
}

impl fmt::Write for Text {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for c in s.chars() {
            let mut utf8 = [0u8; 4];
            let c = c.encode_utf8(&mut utf8).as_bytes();
            let end = self.len + c.len();
            match self.bytes.get_mut(self.len..end) {
                Some(dst) => {
                    dst.copy_from_slice(c);
                    self.len = end;
                }
                None => return Ok(()),
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reason_displays_as_the_bus_said_it() {
        let r = Unreachable::new(&"EtherCAT: slave 1 (0x1001) left OP: now Safe-Operational");
        assert_eq!(
            r.to_string(),
            "EtherCAT: slave 1 (0x1001) left OP: now Safe-Operational"
        );
        assert_eq!(Unreachable::new(&format_args!("{}", 7)).reason(), "7");
    }

    #[test]
    fn a_reason_too_long_is_cut_at_a_character() {
        let long = "é".repeat(REASON_BYTES);
        let r = Unreachable::new(&long);
        assert_eq!(r.reason().len(), REASON_BYTES);
        assert!(r.reason().chars().all(|c| c == 'é'));
        let odd = format!("x{long}");
        assert_eq!(Unreachable::new(&odd).reason().len(), REASON_BYTES - 1);
    }
}
