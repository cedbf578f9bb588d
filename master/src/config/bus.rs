//! `[bus]` and `[rt]`: where the drives are, how often the cycle runs, how it runs.

use serde::Deserialize;

/// `[bus]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BusSection {
    /// `"ethercat"` (CANopen comes later).
    pub kind: String,
    /// Network interface wired to the drives.
    #[serde(default)]
    pub interface: Option<String>,
    /// Instead of an interface: a `gantry-sim` chain file, simulated in this process by the
    /// `gantry` binary (the library opens no simulator: the binary hands the service its
    /// link, see `ethercat::link::LinkFactory`).
    #[serde(default)]
    pub simulator: Option<String>,
    /// Cycle time (µs), 250 to 4000.
    pub cycle_us: u32,
    /// With `simulator`: when gantry exits, write what each simulated drive saw of the
    /// setpoints it took here (JSON, as `gantry-sim --record` writes it), so that a run on
    /// the simulator can be judged afterwards (the binary's `drive_records`).
    #[serde(default)]
    pub simulator_record: Option<String>,
    /// Write every frame to this pcap file.
    #[serde(default)]
    pub pcap: Option<String>,
    /// Distributed clocks: SYNC0 on the slaves at the cycle time (when they have DC).
    #[serde(default = "yes")]
    pub dc: bool,
    /// How much trouble on the wire is ridden through.
    #[serde(default)]
    pub faults: FaultsSection,
}

fn yes() -> bool {
    true
}

/// `[bus.faults]`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields, default)]
pub struct FaultsSection {
    /// Frames lost in a row before every axis stops.
    pub lost_frames_limit: u32,
    /// Cycles in a row with a wrong working counter before every axis stops.
    pub working_counter_limit: u32,
    /// A slave that leaves OP stops every axis, not only its own.
    pub stop_all_on_slave_loss: bool,
}

impl Default for FaultsSection {
    fn default() -> Self {
        Self {
            lost_frames_limit: 3,
            working_counter_limit: 3,
            stop_all_on_slave_loss: false,
        }
    }
}

impl BusSection {
    /// Checks values; the error names the key (below `bus.`) and the reason.
    pub(super) fn check(&self) -> Result<(), (String, String)> {
        if self.kind != "ethercat" {
            return Err((
                "kind".into(),
                format!(
                    "{:?} is not a bus gantry drives yet (\"ethercat\")",
                    self.kind
                ),
            ));
        }
        match (&self.interface, &self.simulator) {
            (Some(_), Some(_)) => {
                return Err((
                    "simulator".into(),
                    "give either interface or simulator, not both".into(),
                ))
            }
            (None, None) => return Err((
                "interface".into(),
                "missing: the network interface wired to the drives (or simulator = \"sim.toml\")"
                    .into(),
            )),
            _ => {}
        }
        if self.simulator_record.is_some() && self.simulator.is_none() {
            return Err((
                "simulator_record".into(),
                "records what simulated drives saw: give it with simulator = \"sim.toml\", \
                 not with a network interface (gantry-sim --record FILE records its own drives)"
                    .into(),
            ));
        }
        if !(250..=4000).contains(&self.cycle_us) {
            return Err((
                "cycle_us".into(),
                format!("{} µs is outside 250 to 4000 µs", self.cycle_us),
            ));
        }
        if self.faults.lost_frames_limit == 0 || self.faults.working_counter_limit == 0 {
            return Err((
                "faults".into(),
                "limits count cycles in a row and must be at least 1".into(),
            ));
        }
        Ok(())
    }
}

/// `[rt]`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields, default)]
pub struct RtSection {
    /// SCHED_FIFO priority of the cycle thread (1–99).
    pub priority: u8,
    /// CPU the cycle thread is pinned to (none: not pinned).
    pub cpu: Option<usize>,
    /// Lock all memory (mlockall) so the cycle never waits for a page.
    pub lock_memory: bool,
    /// Overruns in a row after which every axis stops.
    pub overrun_limit: u32,
}

impl Default for RtSection {
    fn default() -> Self {
        Self {
            priority: 80,
            cpu: None,
            lock_memory: true,
            overrun_limit: 10,
        }
    }
}

impl RtSection {
    pub(super) fn check(&self) -> Result<(), (String, String)> {
        if !(1..=99).contains(&self.priority) {
            return Err((
                "priority".into(),
                format!("{} is outside SCHED_FIFO's 1 to 99", self.priority),
            ));
        }
        if self.overrun_limit == 0 {
            return Err(("overrun_limit".into(), "must be at least 1".into()));
        }
        Ok(())
    }
}
