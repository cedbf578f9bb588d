//! The in-process simulator as a link the library's bus is brought up on: `[bus]
//! simulator` read into a [`SlaveChain`], and the link that reaches it ([`SimLink`]: the
//! wire to a thread of its own, or each frame through the chain in the sending thread).
//! The binary hands a [`Simulator`] to the service (`gantry run`) and the demo; the tests
//! bring a bus up on one and keep its chain. The library (`gantry`) knows no simulator:
//! it sees a [`LinkFactory`].

use std::io::Write;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use gantry::config::Config;
use gantry::ethercat::bus::{Cause, EthercatBus, StartError};
use gantry::ethercat::link::{Link, LinkFactory};
use gantry_sim::chain::SlaveChain;
use gantry_sim::config::SimConfig;

use gantry::canopen::bring_up::StartError as CanStartError;
use gantry::canopen::CanLink;

use crate::can_simulator::{self, SharedBus};
use crate::drive_records;
use crate::embedded::{ChainLink, HostTime, SimWire};

/// How the bus reaches an in-process simulator (`[bus] simulator`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SimLink {
    /// A thread of the simulator's own on the wall clock, at the end of a wire: the cycle
    /// thread exchanges frames with it as with a network interface (`gantry run`).
    Thread,
    /// Each frame passes the chain in the thread that sends it; the chain's time follows
    /// the host's through the bring-up, then stands still but for the steps of whoever
    /// holds it ([`Simulated::step_by_hand`]): tests in lockstep, whatever the host does.
    Lockstep,
}

/// A simulated chain a link was opened to: what its holder inspects and steps.
#[derive(Clone)]
pub struct Simulated {
    chain: Arc<Mutex<SlaveChain>>,
    /// The chain's time on the host's clock, when it is reached in lockstep.
    host_time: Option<HostTime>,
}

impl Simulated {
    /// The chain (lock it to inspect or change slaves between exchanges).
    pub fn chain(&self) -> Arc<Mutex<SlaveChain>> {
        self.chain.clone()
    }

    /// From now on the chain's time stands still but for its holder's steps
    /// ([`SimLink::Lockstep`]); false (nothing changed) on a [`SimLink::Thread`] link.
    pub fn step_by_hand(&self) -> bool {
        self.host_time.as_ref().map(HostTime::stop).is_some()
    }
}

/// Opens the in-process simulator of the chain file `sim` and the link that reaches it by
/// `how`. With [`SimLink::Thread`] the simulator's thread starts here (it inherits this
/// thread's scheduling and CPU).
pub fn open(sim: &str, how: SimLink) -> Result<(Box<dyn Link>, Simulated), StartError> {
    let sim = SimConfig::load(sim)
        .map_err(|e| StartError::link("the simulator's configuration")(Cause::from(e)))?;
    let chain = sim
        .chain()
        .map_err(|e| StartError::link("the simulated slaves")(Cause::from(e)))?;
    let chain = Arc::new(Mutex::new(chain));
    let period = Duration::from_micros(u64::from(sim.cycle_us));
    let (link, host_time): (Box<dyn Link>, _) = match how {
        SimLink::Thread => (
            Box::new(
                SimWire::start(chain.clone(), period)
                    .map_err(|e| StartError::link("the simulator's thread")(Cause::from(e)))?,
            ),
            None,
        ),
        SimLink::Lockstep => {
            let time = chain
                .lock()
                .map(|c| HostTime::start(&c, period))
                .map_err(|_| StartError::NoLink("the simulated chain's lock"))?;
            (
                Box::new(ChainLink::new(chain.clone(), time.clone())),
                Some(time),
            )
        }
    };
    Ok((link, Simulated { chain, host_time }))
}

/// The links of `[bus] simulator`, reached by one [`SimLink`]: what the binary hands the
/// library's bus and service. Keeps the chain it opened last, for its holder and for the
/// drives' records when the bus is closed. A CANopen configuration's simulator is the
/// in-memory CAN bus ([`can_simulator`]): on the wall clock with [`SimLink::Thread`]
/// (`gantry run`), in lockstep with [`SimLink::Lockstep`].
pub struct Simulator {
    how: SimLink,
    opened: Mutex<Option<Simulated>>,
    can: Mutex<Option<SharedBus>>,
}

impl Simulator {
    /// The simulator of any configuration with `[bus] simulator`, reached by `how`.
    pub fn new(how: SimLink) -> Self {
        Self {
            how,
            opened: Mutex::new(None),
            can: Mutex::new(None),
        }
    }

    /// The chain last opened, if any.
    pub fn simulated(&self) -> Option<Simulated> {
        self.opened
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// The chain last opened, if any (lock it to inspect or change slaves).
    pub fn chain(&self) -> Option<Arc<Mutex<SlaveChain>>> {
        self.simulated().map(|s| s.chain)
    }

    /// The simulated CAN bus last opened (a CANopen configuration), if any.
    pub fn can_bus(&self) -> Option<SharedBus> {
        self.can
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// See [`Simulated::step_by_hand`]; false when no chain was opened.
    pub fn step_by_hand(&self) -> bool {
        self.simulated().is_some_and(|s| s.step_by_hand())
    }

    /// Brings the bus of `config` up on its simulator ([`EthercatBus::bring_up_from`]).
    pub fn bring_up(
        &self,
        config: &Config,
        out: &mut (dyn Write + Send),
    ) -> Result<EthercatBus, StartError> {
        EthercatBus::bring_up_from(config, self, out)
    }
}

impl LinkFactory for Simulator {
    fn open(&self, config: &Config) -> Result<Option<Box<dyn Link>>, StartError> {
        let Some(sim) = &config.bus.simulator else {
            return Ok(None);
        };
        if config.bus.kind == "canopen" {
            return Ok(None);
        }
        let (link, simulated) = open(sim, self.how)?;
        *self.opened.lock().unwrap_or_else(PoisonError::into_inner) = Some(simulated);
        Ok(Some(link))
    }

    /// The simulated CANopen nodes of `[bus] simulator` on the in-memory CAN bus at the
    /// configuration's bit rate: on the wall clock ([`SimLink::Thread`]) or in lockstep.
    fn open_can(&self, config: &Config) -> Result<Option<Box<dyn CanLink>>, CanStartError> {
        let Some((link, bus)) = can_simulator::open(config, self.how == SimLink::Thread)? else {
            return Ok(None);
        };
        *self.can.lock().unwrap_or_else(PoisonError::into_inner) = Some(bus);
        Ok(Some(Box::new(link)))
    }

    /// Writes what the simulated drives saw, the shutdown included, to
    /// `[bus] simulator_record` and judges it (`drive_records::report_at_exit`).
    fn closed(&self, config: &Config, out: &mut (dyn Write + Send)) {
        if let (Some(path), Some(bus)) = (&config.bus.simulator_record, self.can_bus()) {
            let records = can_simulator::lock(&bus).records(config);
            drive_records::report_at_exit(config, &records, path, out);
            return;
        }
        let (Some(path), Some(chain)) = (&config.bus.simulator_record, self.chain()) else {
            return;
        };
        let records = chain.lock().map(|c| c.records());
        match records {
            Ok(records) => drive_records::report_at_exit(config, &records, path, out),
            Err(_) => {
                let _ = writeln!(
                    out,
                    "gantry: the simulated chain is poisoned: no drive records"
                );
            }
        }
    }
}
