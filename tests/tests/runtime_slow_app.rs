//! A slow application keeps buffered moves flowing: its task runs every 10 ms and now and
//! then stalls for 50 ms, yet the axis, cycling at 1 ms over the in-process simulator (in
//! lockstep),
//! never stands still between moves — the next move is always queued in time, and the
//! junction takes at most one zero-velocity cycle, as in the kernel alone (with target
//! position monitoring off: with it, a Buffered move waits until the previous is in
//! position).

use gantry::runtime::controller::CommandHandle;
use gantry_kernel::axis::command::{BufferMode, Command, MovePtp, PositioningMode};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_tests::rig::Rig;

/// Cycles (1 ms) between two runs of the application's task.
const TASK_CYCLES: usize = 10;
/// Cycles the application stalls every 7th period.
const STALL_CYCLES: usize = 50;

#[test]
fn buffered_moves_from_a_stalling_10ms_task_run_without_standstill() {
    let mut config = gantry_tests::sim_config_strict(1, 1000);
    // What this test is about is the application keeping the queue filled in time. With
    // target position monitoring (on by default for real axes) a Buffered move starts
    // only when the one before is Done, i.e. in position after the dwell (PLCopen): a
    // standstill at every target by design, tested in `lockstep_target_monitoring` and the
    // kernel's `target_monitoring`. Here moves are Done at their set values.
    config.kernel_axes[0].target_monitoring.enabled = false;
    // In lockstep (`gantry_tests::rig`): the cycle runs 1 ms of network time per cycle;
    // the application's task runs every 10 cycles and stalls for 50 now and then, its
    // requests reaching the engine through the same queues as from another thread.
    let mut rig = Rig::new(&config);
    rig.enable_and_home(0);
    rig.run(100);

    // The application: every 10 ms, keep two moves queued behind the running one; every
    // 7th period it stalls for 50 ms. Moves of 20 mm at 200 mm/s take ~0.15 s.
    let mut handles: Vec<CommandHandle> = Vec::new();
    let mut trace = Vec::new();
    rig.ctl.drain_trace(&mut trace);
    trace.clear();
    let moves = 20;
    let mut period = 0;
    while handles.len() < moves {
        let pending = handles
            .iter()
            .filter(
                |h| !matches!(h.status(), Some(s) if s.is_final() || s == CommandStatus::Active),
            )
            .count();
        if pending < 2 {
            let to = if handles.len() % 2 == 0 { 20.0 } else { 0.0 };
            let mode = if handles.is_empty() {
                BufferMode::Aborting
            } else {
                BufferMode::Buffered
            };
            let m = MovePtp::new(PositioningMode::AbsNormal, to).buffered(mode);
            handles.push(rig.ctl.command(0, Command::MovePtp(m)).unwrap());
        }
        period += 1;
        let pause = if period % 7 == 0 {
            STALL_CYCLES
        } else {
            TASK_CYCLES
        };
        rig.run(pause);
        rig.ctl.drain_trace(&mut trace);
    }
    // The application keeps draining its trace every task period until the last is done.
    let last = handles.last().unwrap();
    for _ in 0..1000 {
        rig.run(TASK_CYCLES);
        rig.ctl.drain_trace(&mut trace);
        if last.status().is_some_and(|s| s.is_final()) {
            break;
        }
    }
    assert_eq!(last.status(), Some(CommandStatus::Done));
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
