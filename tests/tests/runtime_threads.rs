//! No hidden real-time thread. `gantry run` makes its cycle thread SCHED_FIFO; the cycle
//! thread sends and receives its frames itself, so it is gantry's only real-time thread.
//! On the in-process simulator the simulated network answers from a thread of its own,
//! started from the cycle thread (so it inherits its priority and CPU, as drives answer
//! at once): those two, and only those, run in real time. ethercrab's timers would start async-io's reactor thread from
//! the cycle thread at the first frame (a third SCHED_FIFO thread, undocumented) and give
//! the cycle a path to the reactor's timer mutex; gantry gives ethercrab no timers, so the
//! reactor must never start. The cycle thread here is the one `gantry run` spawns
//! (`service::spawn_cycle_thread`), real time (this test runs as root, as `deploy/test.sh`
//! does), cycling at 1 kHz with moves and resets.

use std::sync::atomic::AtomicBool;
use std::sync::{mpsc, Arc};
use std::time::Duration;

use gantry::runtime::controller::Controller;
use gantry::service::{spawn_cycle_thread, CYCLE_THREAD};
use gantry_cli::embedded::SIM_THREAD;
use gantry_cli::simulator::{SimLink, Simulator};
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_tests::threads::threads;

#[test]
fn only_the_cycle_and_the_simulator_run_in_real_time_and_ethercrab_starts_no_reactor() {
    // This test is about the cycle thread, not about riding through lost frames or missed
    // setpoints (`bus_faults`, `claim_*` and the lockstep tests hold the strict limits):
    // on this project's non-preemptible, shared VMs a real-time thread now and then waits
    // milliseconds — three frames in a row are lost, the simulator's thread misses SYNC0
    // periods — and the example's limits would stop the axes it exercises.
    let mut config = gantry_tests::sim_config_with(2, 1000, "[slave.al]\nsync_error_limit = 1000");
    config.bus.faults.lost_frames_limit = 50;
    gantry::runtime::rt::check(&config.rt, false).expect("this test needs root (SCHED_FIFO)");
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel();
    let simulator = Arc::new(Simulator::new(SimLink::Thread));
    let cycle = spawn_cycle_thread(config, true, 1_000_000, stop.clone(), simulator, tx).unwrap();
    let ends = rx.recv().unwrap().expect("the cycle started");
    let ctl = Controller::new(ends, vec!["a0".into(), "a1".into()]);
    for i in 0..2 {
        ctl.command(i, Command::Power(PowerCommand::Enable))
            .unwrap();
        let home = Command::SetPosition {
            position: 0.0,
            relative: false,
        };
        ctl.command(i, home).unwrap();
    }
    std::thread::sleep(Duration::from_millis(200));
    for round in 0..3 {
        let to = if round % 2 == 0 { 5.0 } else { 0.0 };
        let moves: Vec<_> = (0..2)
            .map(|i| {
                let m = MovePtp::new(PositioningMode::AbsNormal, to);
                ctl.command(i, Command::MovePtp(m)).unwrap()
            })
            .collect();
        for m in moves {
            let status = m.wait(Duration::from_secs(5)).unwrap();
            let snap = ctl.snapshot();
            assert_eq!(
                status,
                CommandStatus::Done,
                "{:?} {:?}",
                snap.axes.iter().map(|a| a.error).collect::<Vec<_>>(),
                snap.drives
            );
        }
        let reset = ctl.reset(round % 2).unwrap();
        assert_eq!(
            reset.wait(Duration::from_secs(5)).unwrap(),
            CommandStatus::Done
        );
    }
    let seen = threads();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let figures = cycle.join().unwrap().expect("the cycle ran");
    let listing: Vec<String> = seen
        .iter()
        .map(|t| format!("{} {} policy {}", t.tid, t.name, t.policy))
        .collect();
    eprintln!(
        "{} cycles; threads:\n{}",
        figures.cycles,
        listing.join("\n")
    );
    let mut real_time: Vec<&str> = seen
        .iter()
        .filter(|t| t.real_time())
        .map(|t| t.name.as_str())
        .collect();
    real_time.sort_unstable();
    assert_eq!(
        real_time,
        [CYCLE_THREAD, SIM_THREAD],
        "the real-time threads are the cycle and the simulator's: {listing:?}"
    );
    assert!(
        seen.iter().all(|t| t.name != "async-io"),
        "async-io's reactor thread started (something used an async-io timer): {listing:?}"
    );
    assert!(figures.cycles > 200, "{} cycles", figures.cycles);
}
