//! The phase-lock run behind `runtime_dc_phase.rs` and `runtime_dc_phase_rt.rs`: two
//! simulated drives whose distributed clocks run 300 ppm fast against this host (a poor
//! quartz; real ones are within ±100), in this process. Free-running, the frames walk
//! through the SYNC0 period, 300 µs per second; phase-locked ([`PhaseLock`], what `gantry
//! run` does with DC), the cycle moves its deadlines so the frames keep reaching the
//! reference clock a quarter period after SYNC0.

use gantry::ethercat::bus::EthercatBus;
use gantry::runtime::clock::CycleClock;
use gantry::runtime::cycle::Cycle;
use gantry::runtime::engine::{Engine, LateReply};
use gantry::runtime::phase::PhaseLock;
use gantry_cli::simulator::{SimLink, Simulator};

/// Cycle time (ns).
pub const PERIOD_NS: u64 = 1_000_000;

/// What one run measured.
#[derive(Clone, Copy, Debug)]
pub struct PhaseFigures {
    /// How far the frames moved in the SYNC0 period in 1.4 s free-running (ns).
    pub free_running_moved_ns: i64,
    /// Median error to the target over 1000 locked cycles, after 0.5 s to lock on (ns).
    pub early_median_ns: i64,
    /// The same over the next 1000 cycles (ns).
    pub late_median_ns: i64,
    /// Of those last 1000 frames, how many were within 100 µs of the target.
    pub within_100us: usize,
    /// The target (ns after SYNC0).
    pub target_ns: u64,
    /// Of those last 1000 cycles, how many woke more than 100 µs late (the host's share
    /// of the misses).
    pub late_wakes: usize,
    /// The latest of those wake-ups (ns after its deadline).
    pub worst_wake_ns: u64,
}

/// The median of `v` (sorted in place).
fn median(v: &mut [i64]) -> i64 {
    v.sort_unstable();
    v.get(v.len() / 2).copied().unwrap_or(0)
}

/// Runs free for 1.5 s, then locked for 2.5 s, on the calling thread (the caller makes
/// it real time or not). A late reply waits ([`LateReply::WAIT`]): a frame lost to this
/// host's timing would only blur the figures.
pub fn run() -> PhaseFigures {
    let config = crate::sim_config_with(2, 1000, "dc_drift_ppm = 300");
    let bus = Simulator::new(SimLink::Thread)
        .bring_up(&config, &mut std::io::sink())
        .expect("bus up");
    let cycle = Cycle::from_config(&config, &bus).expect("the cycle");
    assert!(bus.dc().active);
    let (mut engine, _ends) = Engine::new(bus, cycle, 1000, 16);
    engine.set_late_reply(LateReply::WAIT);
    let lock = PhaseLock::new(PERIOD_NS);
    let mut clock = CycleClock::start(PERIOD_NS);
    // The error to the target of each cycle's frame (ns, −period/2 … period/2), and how
    // late the thread woke for it.
    let mut wakes = Vec::with_capacity(1200);
    let mut run = |engine: &mut Engine<EthercatBus>, cycles: usize, locked: bool| {
        let mut errors = Vec::with_capacity(cycles);
        wakes.clear();
        for _ in 0..cycles {
            let wake = clock.wait();
            wakes.push(wake.latency_ns);
            engine.step(wake);
            errors.push(lock.error_ns(engine.bus().dc().cycle_offset_ns));
            if locked {
                clock.shift(engine.phase_correction_ns());
            }
        }
        errors
    };
    run(&mut engine, 100, false);
    let mut first = run(&mut engine, 100, false);
    run(&mut engine, 1200, false);
    let mut last = run(&mut engine, 100, false);
    let free_running_moved_ns =
        (median(&mut last) - median(&mut first)).rem_euclid(PERIOD_NS as i64);
    engine.set_phase_lock(Some(lock));
    run(&mut engine, 500, true);
    let mut early = run(&mut engine, 1000, true);
    let mut late = run(&mut engine, 1000, true);
    let within_100us = late.iter().filter(|e| e.abs() < 100_000).count();
    let late_wakes = wakes.iter().filter(|&&w| w > 100_000).count();
    let worst_wake_ns = wakes.iter().copied().max().unwrap_or(0);
    PhaseFigures {
        free_running_moved_ns,
        early_median_ns: median(&mut early),
        late_median_ns: median(&mut late),
        within_100us,
        target_ns: lock.target_ns(),
        late_wakes,
        worst_wake_ns,
    }
}

impl PhaseFigures {
    /// Prints the figures and checks what holds on any host: the free-running frames
    /// drift as a 300 ppm clock makes them, the locked ones sit at the target (median)
    /// and stay there.
    pub fn check_lock(&self) {
        eprintln!(
            "free-running: the frames moved {} µs in 1.4 s; locked: median error {:.1} µs, \
             then {:.1} µs a second later (target {} µs after SYNC0); {} of 1000 frames \
             within 100 µs; {} woke over 100 µs late, the latest {} µs",
            self.free_running_moved_ns / 1000,
            self.early_median_ns as f64 / 1000.0,
            self.late_median_ns as f64 / 1000.0,
            self.target_ns / 1000,
            self.within_100us,
            self.late_wakes,
            self.worst_wake_ns / 1000
        );
        let moved = self.free_running_moved_ns;
        assert!(
            (250_000..650_000).contains(&moved),
            "a 300 ppm reference moves the frames ~420 µs in 1.4 s, not {moved} ns"
        );
        let (early, late) = (self.early_median_ns, self.late_median_ns);
        assert!(early.abs() < 50_000, "locked on: median error {early} ns");
        assert!(late.abs() < 50_000, "held: median error {late} ns");
        assert!(
            (late - early).abs() < 30_000,
            "no drift while locked: {early} → {late} ns"
        );
    }
}
