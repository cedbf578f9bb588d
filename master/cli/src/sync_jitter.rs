//! `gantry rt-check --can`: when the CANopen cycle thread really hands each SYNC to its
//! link (issue 12 §3: SYNC is sent by the RT thread, so its jitter is the thread's wake-up
//! jitter). The engine runs as `gantry run` runs it — SCHED_FIFO, pinned, memory locked,
//! late replies lost — over the in-memory simulator on the wall clock
//! ([`MemLink::wall_clock`]: simulated CiA 402 servos answer each SYNC with their TPDOs
//! at the bit rate's frame timing), so no CAN hardware is needed. A thin link in front of
//! it stamps CLOCK_MONOTONIC when a SYNC is handed over, into memory taken before the run
//! (the cycle thread neither allocates nor locks for it); the figures are made after.
//!
//! Two figures per run: the SYNC period's deviation, |interval − period| between
//! consecutive SYNCs (what the drives' SYNC consumers see), and the SYNC's lateness
//! against the cycle's deadline (the same quantity as cyclictest's latency, plus the
//! cycle's work before the SYNC: RPDO encode and the kernel step).

use std::io;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;

use gantry::canopen::{CanLink, CanopenBus, Received};
use gantry::config::{Config, RtSection};
use gantry::runtime::bus::CycleBus;
use gantry::runtime::clock::{now_ns, Clock, CycleClock, Wake};
use gantry::runtime::controller::Controller;
use gantry::runtime::cycle::Cycle;
use gantry::runtime::engine::{Engine, LateReply};
use gantry::runtime::histogram::{Histogram, Summary};
use gantry_drives::canopen::cob_id::{NodeId, SYNC_COB_ID};
use gantry_drives::canopen::CanFrame;
use gantry_kernel::axis::command::{Command, MoveDirection, MoveVelocity, PowerCommand};
use gantry_sim::canopen::{CanNode, CanNodeConfig};

use crate::can_simulator::MemLink;

/// Bit rate of the simulated bus (the usual CANopen rate; the bring-up refuses a cycle
/// its PDOs and SYNC do not fit).
pub const BITRATE: u32 = 1_000_000;

/// Cycles run before the measurement: bring-up's first TPDOs, axes enabled and moving.
const SETTLE_CYCLES: usize = 300;

/// Histogram range (µs): deviations beyond land in the last bucket, their max kept.
const HISTOGRAM_US: usize = 20_000;

/// SYNC send times and the deadline of the cycle each was sent in, in memory taken
/// before the run: the cycle thread stores with atomics, never allocates.
#[derive(Debug)]
pub struct SyncLog {
    deadline_ns: AtomicU64,
    /// Time spent inside the simulator's `send` since this cycle's deadline.
    in_link_ns: AtomicU64,
    sent_ns: Box<[AtomicU64]>,
    deadline_of: Box<[AtomicU64]>,
    in_link_of: Box<[AtomicU64]>,
    len: AtomicUsize,
    dropped: AtomicU64,
    recording: std::sync::atomic::AtomicBool,
}

impl SyncLog {
    /// Room for `capacity` SYNCs; recording starts with [`SyncLog::start`].
    pub fn new(capacity: usize) -> Self {
        let zeros = || (0..capacity).map(|_| AtomicU64::new(0)).collect();
        Self {
            deadline_ns: AtomicU64::new(0),
            in_link_ns: AtomicU64::new(0),
            sent_ns: zeros(),
            deadline_of: zeros(),
            in_link_of: zeros(),
            len: AtomicUsize::new(0),
            dropped: AtomicU64::new(0),
            recording: std::sync::atomic::AtomicBool::new(false),
        }
    }

    /// SYNCs from now on are recorded.
    pub fn start(&self) {
        self.recording.store(true, Ordering::Relaxed);
    }

    /// SYNCs from now on are not recorded (the shutdown's, which keep the nodes' SYNC
    /// watchdog fed while they are released, belong to no measured cycle).
    pub fn stop(&self) {
        self.recording.store(false, Ordering::Relaxed);
    }

    /// The cycle that just woke has this deadline.
    fn deadline(&self, ns: u64) {
        self.deadline_ns.store(ns, Ordering::Relaxed);
        self.in_link_ns.store(0, Ordering::Relaxed);
    }

    /// A SYNC handed to the link at `at_ns` (beyond the capacity: counted, not stored).
    fn record(&self, at_ns: u64) {
        if !self.recording.load(Ordering::Relaxed) {
            return;
        }
        let i = self.len.load(Ordering::Relaxed);
        match (
            self.sent_ns.get(i),
            self.deadline_of.get(i),
            self.in_link_of.get(i),
        ) {
            (Some(s), Some(d), Some(l)) => {
                s.store(at_ns, Ordering::Relaxed);
                d.store(self.deadline_ns.load(Ordering::Relaxed), Ordering::Relaxed);
                l.store(self.in_link_ns.load(Ordering::Relaxed), Ordering::Relaxed);
                self.len.store(i + 1, Ordering::Release);
            }
            _ => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// (send time, deadline of its cycle) of every SYNC recorded, in order; with
    /// `without_link`, each send time less the time the simulator spent in the frames
    /// sent before it in its cycle (the RPDOs: on a real link a `write` of a few µs, here
    /// the simulated nodes' reaction, which is not the cycle thread's own).
    pub fn entries(&self, without_link: bool) -> Vec<(u64, u64)> {
        let n = self.len.load(Ordering::Acquire);
        (0..n)
            .map(|i| {
                let link = if without_link {
                    self.in_link_of[i].load(Ordering::Relaxed)
                } else {
                    0
                };
                (
                    self.sent_ns[i].load(Ordering::Relaxed).saturating_sub(link),
                    self.deadline_of[i].load(Ordering::Relaxed),
                )
            })
            .collect()
    }
}

/// The link in front of the simulator: stamps each SYNC as the cycle thread hands it
/// over (before the link's own work).
pub struct SyncStampLink<L> {
    inner: L,
    log: Arc<SyncLog>,
}

impl<L: CanLink> SyncStampLink<L> {
    /// Stamps into `log` what goes to `inner`.
    pub fn new(inner: L, log: Arc<SyncLog>) -> Self {
        Self { inner, log }
    }
}

impl<L: CanLink> CanLink for SyncStampLink<L> {
    fn send(&mut self, frame: &CanFrame) -> io::Result<()> {
        let at = now_ns();
        if frame.id() == SYNC_COB_ID {
            self.log.record(at);
            return self.inner.send(frame);
        }
        let sent = self.inner.send(frame);
        self.log
            .in_link_ns
            .fetch_add(now_ns().saturating_sub(at), Ordering::Relaxed);
        sent
    }

    fn receive(&mut self, deadline_ns: u64) -> io::Result<Option<Received>> {
        self.inner.receive(deadline_ns)
    }

    fn now_ns(&self) -> u64 {
        self.inner.now_ns()
    }
}

/// The production clock, telling the log each cycle's deadline.
struct LoggedClock {
    clock: CycleClock,
    log: Arc<SyncLog>,
}

impl Clock for LoggedClock {
    fn wait(&mut self) -> Wake {
        let wake = self.clock.wait();
        self.log.deadline(wake.deadline_ns);
        wake
    }

    fn shift(&mut self, ns: i64) {
        self.clock.shift(ns);
    }
}

/// What a run measured.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct SyncJitter {
    /// |interval − period| between consecutive SYNCs.
    pub deviation: Summary,
    /// SYNC handed to the link minus the cycle's deadline.
    pub lateness: Summary,
    /// [`SyncJitter::deviation`] less the simulator's time in the RPDO sends before
    /// each SYNC (the cycle thread's own part).
    pub deviation_own: Summary,
    /// [`SyncJitter::lateness`] less the same.
    pub lateness_own: Summary,
    /// Cycles run while recording.
    pub cycles: u64,
    /// SYNCs recorded.
    pub syncs: u64,
    /// From the first recorded SYNC to the last (ns).
    pub span_ns: u64,
    /// SYNCs sent before their cycle's deadline (none should be: the cycle sleeps to it).
    pub early: u64,
    /// Frames the master counted lost (TPDOs not in by the deadline) while recording.
    pub lost: u64,
    /// Whether SCHED_FIFO, pinning and memory locking were granted.
    pub real_time: bool,
}

/// The figures from the log: consecutive SYNCs' |interval − period| and each SYNC's
/// lateness against its cycle's deadline.
pub fn figures(entries: &[(u64, u64)], period_ns: u64) -> (Summary, Summary) {
    let mut deviation = Histogram::new(HISTOGRAM_US);
    let mut lateness = Histogram::new(HISTOGRAM_US);
    for w in entries.windows(2) {
        let interval = w[1].0.saturating_sub(w[0].0);
        deviation.record(interval.abs_diff(period_ns));
    }
    for &(sent, deadline) in entries {
        lateness.record(sent.saturating_sub(deadline));
    }
    (deviation.summary(), lateness.summary())
}

/// The configuration of the run: `drives` CSP servos (nodes 1..), 1 Mbit/s, `cycle_us`.
pub fn config(drives: u8, cycle_us: u32, rt: &RtSection) -> Result<Config, String> {
    let mut text = format!(
        "[bus]\nkind = \"canopen\"\ninterface = \"mem0\"\nbitrate = {BITRATE}\n\
         cycle_us = {cycle_us}\n"
    );
    for node in 1..=drives {
        text += &format!(
            "[[axis]]\nname = \"a{node}\"\nnode = {node}\npdo = \"csp\"\n\
             scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
             max = {{ speed = 200.0, acceleration = 2000.0, jerk = 20000.0 }}\n"
        );
    }
    let mut config = Config::parse(&text, "rt-check --can").map_err(|e| e.to_string())?;
    config.rt = *rt;
    Ok(config)
}

/// Runs `drives` simulated servos at `cycle_us` for `seconds` in a cycle thread made as
/// `gantry run` makes it (`rt`: priority, CPU, memory locking; refused → measured
/// anyway, `real_time` false, replies waited for as `--no-rt` does), every axis moving,
/// and measures its SYNCs.
pub fn measure(
    rt: RtSection,
    drives: u8,
    cycle_us: u32,
    seconds: f64,
) -> Result<SyncJitter, String> {
    if drives == 0 || drives > 127 {
        return Err(format!(
            "--can {drives}: a CANopen network has nodes 1 to 127"
        ));
    }
    let config = config(drives, cycle_us, &rt)?;
    let period_ns = u64::from(cycle_us) * 1000;
    let cycles = (seconds * 1e6 / f64::from(cycle_us)).max(2.0) as usize;
    let log = Arc::new(SyncLog::new(cycles + 16));
    let thread_log = log.clone();
    let handle = std::thread::Builder::new()
        .name("gantry-cycle".into())
        .stack_size(gantry::service::CYCLE_STACK_BYTES)
        .spawn(move || run(&config, &thread_log, period_ns, cycles))
        .map_err(|e| format!("the cycle thread: {e}"))?;
    let (real_time, lost) = handle
        .join()
        .map_err(|_| "the cycle thread panicked".to_string())??;
    let entries = log.entries(false);
    let (deviation, lateness) = figures(&entries, period_ns);
    let (deviation_own, lateness_own) = figures(&log.entries(true), period_ns);
    Ok(SyncJitter {
        deviation,
        lateness,
        deviation_own,
        lateness_own,
        cycles: cycles as u64,
        syncs: entries.len() as u64,
        span_ns: match (entries.first(), entries.last()) {
            (Some(a), Some(b)) => b.0 - a.0,
            _ => 0,
        },
        early: entries
            .iter()
            .filter(|(sent, deadline)| sent < deadline)
            .count() as u64,
        lost,
        real_time,
    })
}

/// The cycle thread: real time, bring-up on the simulator, axes enabled and moving,
/// then `cycles` recorded cycles. (real time granted, frames lost while recording).
fn run(
    config: &Config,
    log: &Arc<SyncLog>,
    period_ns: u64,
    cycles: usize,
) -> Result<(bool, u64), String> {
    let real_time = gantry::runtime::rt::enter(&config.rt).is_ok();
    let nodes = (1..=config.axes.len() as u8)
        .map(|n| {
            let id = NodeId::new(n).map_err(|e| e.to_string())?;
            CanNode::new(CanNodeConfig::servo(id)).map_err(|e| e.to_string())
        })
        .collect::<Result<Vec<_>, String>>()?;
    let (link, _bus) = MemLink::wall_clock(nodes, Some(BITRATE), period_ns);
    let link = SyncStampLink::new(link, log.clone());
    let bus = CanopenBus::bring_up_on(config, Box::new(link), &mut io::sink())
        .map_err(|e| format!("the CANopen bring-up: {e}"))?;
    let cycle = Cycle::from_config(config, &bus).map_err(|e| e.to_string())?;
    let (mut engine, ends) = Engine::new(bus, cycle, config.rt.overrun_limit, 1024);
    engine.set_late_reply(if real_time {
        LateReply::Lost
    } else {
        LateReply::WAIT
    });
    let names = config.axes.iter().map(|a| a.name.clone()).collect();
    let ctl = Controller::new(ends, names);
    let mut clock = LoggedClock {
        clock: CycleClock::start(period_ns),
        log: log.clone(),
    };
    for a in 0..config.axes.len() {
        let _ = ctl.command(a, Command::Power(PowerCommand::Enable));
    }
    for i in 0..SETTLE_CYCLES {
        if i == SETTLE_CYCLES / 2 {
            for a in 0..config.axes.len() {
                let v = MoveVelocity::new(MoveDirection::Positive, 20.0);
                let _ = ctl.command(a, Command::MoveVelocity(v));
            }
        }
        engine.cycle(&mut clock);
    }
    let lost_before = engine.bus.counters().lost;
    log.start();
    for _ in 0..cycles {
        engine.cycle(&mut clock);
    }
    let lost = engine.bus.counters().lost - lost_before;
    log.stop();
    engine.into_bus().shut_down(&mut io::sink());
    Ok((real_time, lost))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The figures are made from the log as documented: deviation of consecutive
    /// intervals from the period, lateness against each cycle's deadline.
    #[test]
    fn figures_are_interval_deviations_and_lateness() {
        let p = 1_000_000;
        // Deadlines 0, 1, 2, 3 ms; SYNCs 10, 30, 20 and 2010 µs late (the last one after
        // a 2 ms stall).
        let entries = [
            (10_000, 0),
            (p + 30_000, p),
            (2 * p + 20_000, 2 * p),
            (3 * p + 2_010_000, 3 * p),
        ];
        let (dev, late) = figures(&entries, p);
        // Intervals 1.020, 0.990, 2.990 ms: deviations 20, 10, 1990 µs.
        assert_eq!(dev.count, 3);
        assert_eq!(dev.max_us, 1990.0);
        assert_eq!(dev.p50_us, 21.0, "{dev:?}");
        assert_eq!(late.count, 4);
        assert_eq!(late.max_us, 2010.0);
    }

    /// A log records nothing before it is started, and counts what does not fit.
    #[test]
    fn the_log_keeps_what_fits_and_counts_the_rest() {
        let log = SyncLog::new(2);
        log.record(5);
        log.start();
        log.deadline(7);
        log.record(10);
        log.record(20);
        log.record(30);
        assert_eq!(log.entries(false), vec![(10, 7), (20, 7)]);
        let log2 = SyncLog::new(1);
        log2.start();
        log2.deadline(100);
        log2.in_link_ns.fetch_add(3, Ordering::Relaxed);
        log2.record(110);
        assert_eq!(log2.entries(false), vec![(110, 100)]);
        assert_eq!(log2.entries(true), vec![(107, 100)]);
        // A new cycle starts its link time from zero.
        log2.deadline(200);
        assert_eq!(log2.in_link_ns.load(Ordering::Relaxed), 0);
        assert_eq!(log.dropped.load(Ordering::Relaxed), 1);
    }

    /// The whole measurement, as any user may run it (priority 1, not pinned, memory not
    /// locked; SCHED_FIFO only if allowed): every recorded cycle sent one SYNC, none
    /// before its cycle's deadline, on the wall clock (the SYNCs span the recorded
    /// cycles' periods, as they would not in lockstep). No bound on the tails: these
    /// shared machines stall for milliseconds.
    #[test]
    fn the_measurement_stamps_one_sync_per_cycle_on_the_wall_clock() {
        let rt = RtSection {
            priority: 1,
            cpu: None,
            lock_memory: false,
            overrun_limit: 1000,
        };
        let j = measure(rt, 2, 2000, 0.4).unwrap();
        assert_eq!(j.cycles, 200);
        assert_eq!(j.syncs, 200, "{j:?}");
        assert_eq!(j.deviation.count, 199);
        assert_eq!(j.lateness.count, 200);
        assert_eq!(j.lateness_own.count, 200);
        assert!(j.lateness_own.p50_us <= j.lateness.p50_us, "{j:?}");
        assert_eq!(j.early, 0, "{j:?}");
        assert!(j.span_ns >= 198 * 2_000_000, "{j:?}");
    }

    /// As root (deploy/test.sh): the production thread — SCHED_FIFO 80, pinned, memory
    /// locked — and one SYNC per cycle.
    #[test]
    #[ignore = "needs root or CAP_SYS_NICE + CAP_IPC_LOCK (SCHED_FIFO, mlockall); deploy/test.sh runs it"]
    fn the_measurement_runs_in_real_time_as_root() {
        let rt = RtSection {
            priority: 80,
            cpu: Some(0),
            lock_memory: true,
            overrun_limit: 1000,
        };
        let j = measure(rt, 4, 2000, 1.0).unwrap();
        assert!(j.real_time, "SCHED_FIFO, pinning or mlockall refused");
        assert_eq!(j.syncs, j.cycles, "{j:?}");
    }
}
