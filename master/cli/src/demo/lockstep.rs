//! gantry's engine stepped by the demo's own thread, in lockstep: each cycle moves the
//! network's time on by one cycle time ([`StepClock`]), so a demo is deterministic, needs
//! no root and no real-time thread, and its drives see a master exactly on time. One
//! wrapper for every bus the demos run on (the in-process EtherCAT network, the simulated
//! axes' bus).

use gantry::config::Config;
use gantry::runtime::bus::CycleBus;
use gantry::runtime::clock::StepClock;
use gantry::runtime::controller::Controller;
use gantry::runtime::cycle::Cycle;
use gantry::runtime::engine::Engine;

use super::DemoError;

/// What moves the network's time to the time it is given (ns): the simulated chain
/// stepped by hand, or nothing where the drives answer within the exchange.
pub type Advance = Box<dyn FnMut(u64) + Send>;

/// gantry's engine over a demo's bus `B`, stepped by the demo's thread.
pub struct Lockstep<B: CycleBus> {
    /// The engine of `gantry run`.
    pub engine: Engine<B>,
    /// The application's side of it.
    pub ctl: Controller,
    clock: StepClock<Advance>,
}

impl<B: CycleBus> Lockstep<B> {
    /// The engine of `config` on `bus` as `gantry run` builds it, minus the real-time
    /// thread, with `trace_ring` samples in its trace ring; its clock starts at the
    /// network's time `start_ns` and moves it on through `advance`.
    pub fn start(
        bus: B,
        config: &Config,
        trace_ring: usize,
        start_ns: u64,
        advance: Advance,
    ) -> Result<Self, DemoError> {
        let cycle = Cycle::from_config(config, &bus)?;
        let (engine, ends) = Engine::new(bus, cycle, config.rt.overrun_limit, trace_ring);
        let names = config.axes.iter().map(|a| a.name.clone()).collect();
        Ok(Self {
            engine,
            ctl: Controller::new(ends, names),
            clock: StepClock::new(u64::from(config.bus.cycle_us) * 1000, start_ns, advance),
        })
    }

    /// One cycle; false once the engine has ended (after a shutdown).
    pub fn cycle(&mut self) -> bool {
        self.engine.cycle(&mut self.clock)
    }

    /// Cycles run.
    pub fn cycles(&self) -> u64 {
        self.engine.counters().cycles
    }

    /// Kernel time (s).
    pub fn time(&self) -> f64 {
        self.engine.cycle.kernel.time()
    }

    /// The kernel's cycle time (s).
    pub fn cycle_time(&self) -> f64 {
        self.engine.cycle.kernel.cycle_time()
    }
}
