//! A slow application keeps buffered moves flowing: its task runs every 10 ms and now and
//! then stalls for 50 ms, yet the axis, cycling at 1 ms over the in-process simulator,
//! never stands still between moves — the next move is always queued in time, and the
//! junction takes at most one zero-velocity cycle, as in the kernel alone (with target
//! position monitoring off: with it, a Buffered move waits until the previous is in
//! position).

use std::sync::mpsc;
use std::time::Duration;

use gantry::ethercat::bus::EthercatBus;
use gantry::runtime::clock::CycleClock;
use gantry::runtime::controller::Controller;
use gantry::runtime::cycle::Cycle;
use gantry::runtime::engine::{Engine, LateReply};
use gantry_kernel::axis::command::{BufferMode, Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;

#[test]
fn buffered_moves_from_a_stalling_10ms_task_run_without_standstill() {
    let mut config = gantry_tests::sim_config(1, 1000);
    // What this test is about is the application keeping the queue filled in time. With
    // target position monitoring (on by default for real axes) a Buffered move starts
    // only when the one before is Done, i.e. in position after the dwell (PLCopen; issue
    // 11 §5): a standstill at every target by design, tested in `lockstep_target_monitoring`
    // and the kernel's `target_monitoring`. Here moves are Done at their set values.
    config.kernel_axes[0].target_monitoring.enabled = false;
    let (tx, rx) = mpsc::channel();
    let cycle_thread = std::thread::spawn(move || {
        let bus = EthercatBus::bring_up(&config, &mut std::io::sink()).unwrap();
        let cycle = Cycle::from_config(&config, &bus).unwrap();
        let (mut engine, ends) = Engine::new(bus, cycle, 1000, 100_000);
        // Not a real-time thread: a late reply is this host's doing, not a lost frame.
        engine.set_late_reply(LateReply::WAIT);
        tx.send(ends).unwrap();
        let mut clock = CycleClock::start(1_000_000);
        while engine.step(clock.wait()) {}
    });
    let ctl = Controller::new(rx.recv().unwrap(), vec!["x".into()]);
    ctl.command(0, Command::Power(PowerCommand::Enable))
        .unwrap();
    let home = ctl
        .command(
            0,
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
        )
        .unwrap();
    home.wait(Duration::from_secs(2)).unwrap();
    std::thread::sleep(Duration::from_millis(100));

    // The application: every 10 ms, keep two moves queued behind the running one; every
    // 7th period it stalls for 50 ms. Moves of 20 mm at 200 mm/s take ~0.15 s.
    let mut handles = Vec::new();
    let mut trace = Vec::new();
    ctl.drain_trace(&mut trace);
    trace.clear();
    let moves = 20;
    let mut period = 0;
    while handles.len() < moves {
        let pending = handles
            .iter()
            .filter(|h: &&gantry::runtime::controller::CommandHandle| {
                !matches!(h.status(), Some(s) if s.is_final() || s == CommandStatus::Active)
            })
            .count();
        if pending < 2 {
            let to = if handles.len() % 2 == 0 { 20.0 } else { 0.0 };
            let mode = if handles.is_empty() {
                BufferMode::Aborting
            } else {
                BufferMode::Buffered
            };
            let m = MovePtp::new(PositioningMode::AbsNormal, to).buffered(mode);
            handles.push(ctl.command(0, Command::MovePtp(m)).unwrap());
        }
        period += 1;
        let pause = if period % 7 == 0 { 50 } else { 10 };
        std::thread::sleep(Duration::from_millis(pause));
        ctl.drain_trace(&mut trace);
    }
    let last = handles
        .last()
        .unwrap()
        .wait(Duration::from_secs(10))
        .unwrap();
    ctl.drain_trace(&mut trace);
    ctl.shutdown().unwrap();
    cycle_thread.join().unwrap();
    assert_eq!(last, CommandStatus::Done);
    for (i, h) in handles.iter().enumerate() {
        assert_eq!(h.status(), Some(CommandStatus::Done), "move {i}");
    }
    // From the first motion to the end of the last move: never two zero-velocity cycles
    // in a row.
    let moving: Vec<f64> = trace.iter().map(|s| s.set_velocity[0]).collect();
    let start = moving.iter().position(|v| v.abs() > 0.0).unwrap();
    let end = moving.iter().rposition(|v| v.abs() > 0.0).unwrap();
    let mut run = 0;
    let mut worst = 0;
    for v in &moving[start..=end] {
        run = if v.abs() < 1e-12 { run + 1 } else { 0 };
        worst = worst.max(run);
    }
    let stalls = period / 7;
    eprintln!(
        "{moves} buffered moves over {} cycles, application stalled {stalls} times for 50 ms; longest zero-velocity run between moves: {worst} cycle(s)",
        end - start + 1
    );
    assert!(
        worst <= 1,
        "a standstill between buffered moves: {worst} cycles"
    );
    assert!(stalls >= 3, "the application did stall");
}
