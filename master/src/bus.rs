//! The bus a configuration names (`[bus] kind`): EtherCAT or CANopen, brought up and shut
//! down by kind, and run by the same engine through [`CycleBus`]. An enum rather than a
//! trait object: the cycle calls the bus a dozen times per period, each a match, no
//! indirection, and the service still has one engine type.

use std::io::Write;

use thiserror::Error;

use crate::canopen::{self, CanopenBus, SocketLink};
use crate::config::Config;
use crate::ethercat::bus::{self as ethercat, EthercatBus};
use crate::ethercat::link::LinkFactory;
use crate::runtime::bus::{
    BusCounters, CanNodeStatus, CycleBus, DriveError, Reply, Restored, Unreachable,
};
use crate::runtime::sdo::{SdoBuffer, SdoEnded, SdoTransfer};
use gantry_kernel::axis::command::CommandError;

/// Either bus.
// One per process, made once: the size difference costs nothing worth a box.
#[allow(clippy::large_enum_variant)]
pub enum AnyBus {
    /// EtherCAT (`kind = "ethercat"`).
    Ethercat(EthercatBus),
    /// CANopen (`kind = "canopen"`).
    Canopen(CanopenBus),
}

/// Why the bus did not come up.
#[derive(Debug, Error)]
pub enum BusError {
    /// The EtherCAT bus.
    #[error(transparent)]
    Ethercat(#[from] ethercat::StartError),
    /// The CANopen bus.
    #[error(transparent)]
    Canopen(#[from] canopen::bring_up::StartError),
    /// The CAN interface could not be opened.
    #[error("CANopen: {0}")]
    CanInterface(#[from] gantry_link::can_socket::CanSocketError),
    /// A CANopen configuration with neither an interface nor a simulator.
    #[error(
        "CANopen: no link: the configuration has no [bus] interface, and no simulator \
         runs in this process for its [bus] simulator"
    )]
    NoCanLink,
}

impl AnyBus {
    /// Brings the bus of `config` up: on `[bus] interface`, or on the link `links` opens
    /// (the binary's in-process simulator). Prints its steps to `out`.
    pub fn bring_up(
        config: &Config,
        links: &dyn LinkFactory,
        out: &mut (dyn Write + Send),
    ) -> Result<Self, BusError> {
        if config.bus.kind == "canopen" {
            let link: Box<dyn canopen::CanLink> = match &config.bus.interface {
                Some(interface) => Box::new(SocketLink::open(interface)?),
                None => links.open_can(config)?.ok_or(BusError::NoCanLink)?,
            };
            return Ok(Self::Canopen(CanopenBus::bring_up_on(config, link, out)?));
        }
        Ok(Self::Ethercat(EthercatBus::bring_up_from(
            config, links, out,
        )?))
    }

    /// Takes the drives out of operation and closes the link (EtherCAT: to PreOp;
    /// CANopen: NMT pre-operational).
    pub fn shut_down(self, out: &mut (dyn Write + Send)) {
        match self {
            Self::Ethercat(b) => b.shut_down(out),
            Self::Canopen(b) => {
                b.shut_down(out);
            }
        }
    }

    /// The EtherCAT bus, if it is one.
    pub fn ethercat(&self) -> Option<&EthercatBus> {
        match self {
            Self::Ethercat(b) => Some(b),
            Self::Canopen(_) => None,
        }
    }

    /// The CANopen bus, if it is one.
    pub fn canopen(&self) -> Option<&CanopenBus> {
        match self {
            Self::Canopen(b) => Some(b),
            Self::Ethercat(_) => None,
        }
    }
}

/// Runs `$body` with `$b` bound to whichever bus it is.
macro_rules! with_bus {
    ($bus:expr, $b:ident => $body:expr) => {
        match $bus {
            AnyBus::Ethercat($b) => $body,
            AnyBus::Canopen($b) => $body,
        }
    };
}

impl CycleBus for AnyBus {
    fn drives(&self) -> usize {
        with_bus!(self, b => b.drives())
    }
    fn inputs(&self, drive: usize) -> &[u8] {
        with_bus!(self, b => b.inputs(drive))
    }
    fn outputs(&self, drive: usize) -> &[u8] {
        with_bus!(self, b => b.outputs(drive))
    }
    fn outputs_mut(&mut self, drive: usize) -> &mut [u8] {
        with_bus!(self, b => b.outputs_mut(drive))
    }
    fn exchange(&mut self, deadline_ns: u64) -> Reply {
        with_bus!(self, b => b.exchange(deadline_ns))
    }
    fn fault(&self, drive: usize) -> Option<&Unreachable> {
        with_bus!(self, b => b.fault(drive))
    }
    fn inputs_fresh(&self, drive: usize) -> bool {
        with_bus!(self, b => b.inputs_fresh(drive))
    }
    fn drive_error(&self, drive: usize) -> Option<DriveError> {
        with_bus!(self, b => b.drive_error(drive))
    }
    fn any_fault(&self) -> bool {
        with_bus!(self, b => b.any_fault())
    }
    fn clear_faults(&mut self) {
        with_bus!(self, b => b.clear_faults())
    }
    fn counters(&self) -> BusCounters {
        with_bus!(self, b => b.counters())
    }
    fn start_operation(&mut self) {
        with_bus!(self, b => b.start_operation())
    }
    fn start_restore(&mut self, drive: usize, now_ns: u64, timeout_ns: u64) -> bool {
        with_bus!(self, b => b.start_restore(drive, now_ns, timeout_ns))
    }
    fn take_restored(&mut self) -> Option<Result<Restored, CommandError>> {
        with_bus!(self, b => b.take_restored())
    }
    fn restore_timeout_ns(&self) -> u64 {
        with_bus!(self, b => b.restore_timeout_ns())
    }
    fn dc_offset_ns(&self) -> Option<u64> {
        with_bus!(self, b => b.dc_offset_ns())
    }
    fn dc_measured(&self) -> bool {
        with_bus!(self, b => b.dc_measured())
    }
    fn start_sdo(
        &mut self,
        transfer: &SdoTransfer,
        buffer: SdoBuffer,
        now_ns: u64,
    ) -> Result<(), SdoEnded> {
        with_bus!(self, b => b.start_sdo(transfer, buffer, now_ns))
    }
    fn take_sdo(&mut self) -> Option<SdoEnded> {
        with_bus!(self, b => b.take_sdo())
    }
    fn can_node(&self, drive: usize) -> Option<CanNodeStatus> {
        with_bus!(self, b => b.can_node(drive))
    }
}
