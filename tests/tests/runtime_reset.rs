//! `gantry reset` of an axis whose slave left OP, through the engine on the in-process
//! simulator in lockstep, whose drives take 40 ms from SafeOp to Op: the reset waits while
//! the bus brings the slave back — acknowledge its
//! error, request OP, poll until it is there — doing one register access per cycle
//! beside the process data, so no cycle carries more than the process-data frame and one
//! access; then the axis' Reset follows. A slave that does not come back fails the reset
//! with the reason as text once the timeout passes.

use gantry::runtime::controller::CommandHandle;
use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;

/// The simulated drives' SafeOp→Op time.
const SAFEOP_TO_OP_MS: u64 = 40;

/// The lockstep rig (`gantry_tests::rig`): one cycle is 1 ms of the network's time.
struct Rig(gantry_tests::rig::Rig);

impl Rig {
    fn new() -> Self {
        // Drives whose firmware takes 40 ms from SafeOp to Op (the default is 5 ms), with
        // the standard sync supervision.
        let config = gantry_tests::sim_config_with(
            2,
            1000,
            &format!(
                "[slave.al]\nsafeop_to_op_ms = {SAFEOP_TO_OP_MS}\nsync_error_limit = {}\n",
                gantry_tests::DEFAULT_SYNC_ERROR_LIMIT
            ),
        );
        Self(gantry_tests::rig::Rig::new(&config))
    }

    /// Runs one cycle; returns the replies (frames) it took.
    fn cycle(&mut self) -> u64 {
        let before = self.0.engine.bus().replies();
        self.0.cycle();
        self.0.engine.bus().replies() - before
    }

    fn run(&mut self, n: usize) {
        for _ in 0..n {
            self.cycle();
        }
    }

    /// Cycles until `h` is final; returns its status, the cycles and the most frames a
    /// cycle took meanwhile.
    fn until_final(&mut self, h: &CommandHandle) -> (CommandStatus, u32, u64) {
        let (mut cycles, mut most) = (0, 0);
        loop {
            let frames = self.cycle();
            if frames > 2 {
                eprintln!("cycle {cycles}: {frames} frames");
            }
            most = most.max(frames);
            cycles += 1;
            // The snapshot is published every 10 cycles.
            if cycles % 10 == 0 {
                if let Some(s) = h.status().filter(CommandStatus::is_final) {
                    return (s, cycles, most);
                }
            }
            assert!(cycles < 20_000, "the reset never finished");
        }
    }

    fn al_status(&self, i: usize) -> u16 {
        self.0.chain.lock().unwrap().slaves()[i].al_status()
    }

    fn state(&self, i: usize) -> AxisState {
        self.0.ctl.snapshot().axes[i].state
    }
}

/// Pulls the cable behind slave 0 for longer than the slave's process-data watchdog
/// (100 ms): slave 1 drops to SafeOp with the watchdog error, its axis stops.
fn lose_slave_1(rig: &mut Rig) {
    for i in 0..2 {
        rig.0
            .ctl
            .command(i, Command::Power(PowerCommand::Enable))
            .unwrap();
    }
    // The start takes its time (the phase lock holds, then each slave's 40 ms to Op, then
    // the enable): up to a second, in steps of the snapshot's 10 cycles.
    for _ in 0..100 {
        if (0..2).all(|i| rig.state(i) == AxisState::Standstill) {
            break;
        }
        rig.run(10);
    }
    assert_eq!(rig.state(1), AxisState::Standstill);
    rig.0.chain.lock().unwrap().cut_before(Some(1));
    rig.run(250);
    rig.0.chain.lock().unwrap().cut_before(None);
    rig.run(20);
    assert_eq!(rig.al_status(1), 0x14, "SafeOp with the watchdog error");
    assert_eq!(rig.state(1), AxisState::ErrorStop);
}

/// One test: the bus can start once per process.
#[test]
fn resets_of_a_lost_slave() {
    let mut rig = Rig::new();
    a_reset_brings_the_slave_back_one_access_per_cycle(&mut rig);
    a_slave_that_stays_away_fails_the_reset_with_the_reason(&mut rig);
}

fn a_reset_brings_the_slave_back_one_access_per_cycle(rig: &mut Rig) {
    lose_slave_1(rig);
    let reset = rig.0.ctl.reset(1).unwrap();
    let (status, cycles, most) = rig.until_final(&reset);
    eprintln!("reset: {status:?} after {cycles} cycles (ms); at most {most} frames in a cycle");
    // The bug this guards: the AL status read once right after requesting Op called a
    // slave still on its way "refused".
    assert_eq!(status, CommandStatus::Done, "the axis' Reset followed");
    assert!(
        u64::from(cycles) >= SAFEOP_TO_OP_MS,
        "waited for the drive's {SAFEOP_TO_OP_MS} ms to Op: {cycles} cycles of 1 ms"
    );
    assert_eq!(rig.al_status(1), 0x08, "back in OP");
    assert!(
        most <= 2,
        "a cycle carried {most} frames: the process data and one access at most"
    );
    // Read, acknowledge, read, request OP, then reads until the drive is in Op.
    assert!(cycles >= 5);
    // The drive faulted with its slave: Disabled after the reset, enabled again it moves.
    assert_eq!(rig.state(1), AxisState::Disabled);
    rig.0
        .ctl
        .command(1, Command::Power(PowerCommand::Enable))
        .unwrap();
    rig.run(100);
    assert_eq!(rig.state(1), AxisState::Standstill);
    assert_eq!(rig.state(0), AxisState::Standstill, "axis 0 never stopped");
}

fn a_slave_that_stays_away_fails_the_reset_with_the_reason(rig: &mut Rig) {
    rig.0.engine.set_recovery_timeout(50_000_000);
    lose_slave_1(rig);
    rig.0.chain.lock().unwrap().cut_before(Some(1));
    let reset = rig.0.ctl.reset(1).unwrap();
    let start = std::time::Instant::now();
    let (status, _, most) = rig.until_final(&reset);
    let waited = start.elapsed();
    let CommandStatus::Error(e) = status else {
        panic!("the reset of an unplugged slave ended {status:?}");
    };
    assert_eq!(
        e.to_string(),
        "Reset: bus slave 0x1001 is not back in operation: it does not answer (cable, \
         power?)"
    );
    assert!(
        waited >= std::time::Duration::from_millis(50),
        "tried for the whole timeout: {waited:?}"
    );
    assert!(most <= 2);
    assert_eq!(rig.state(1), AxisState::ErrorStop);
    // Plugged back, a second reset succeeds.
    rig.0.chain.lock().unwrap().cut_before(None);
    rig.0.engine.set_recovery_timeout(10_000_000_000);
    let reset = rig.0.ctl.reset(1).unwrap();
    assert_eq!(rig.until_final(&reset).0, CommandStatus::Done);
}
