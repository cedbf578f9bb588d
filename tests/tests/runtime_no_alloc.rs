//! The cycle thread allocates nothing: the engine runs at 1 kHz over the in-process
//! simulator (4 axes) while a counting allocator watches the cycle thread for 3000 cycles,
//! as the application sends moves and resets. (That it takes no lock is
//! `runtime_no_lock.rs`.)

use std::sync::mpsc;
use std::time::Duration;

use gantry::config::Config;
use gantry::ethercat::bus::EthercatBus;
use gantry::runtime::clock::CycleClock;
use gantry::runtime::controller::Controller;
use gantry::runtime::engine::{Engine, LateReply};
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};

mod counting {
    include!("../../kernel/tests/common/counting_alloc.rs");
}

#[global_allocator]
static ALLOC: counting::Counting = counting::Counting;

#[test]
fn the_cycle_thread_does_not_allocate() {
    let config: Config = gantry_tests::sim_config(4, 1000);
    let (tx, rx) = mpsc::channel();
    let cycle_thread = std::thread::spawn(move || {
        let (bus, cycle, health) = EthercatBus::bring_up(&config, &mut std::io::sink()).unwrap();
        let (mut engine, ends) = Engine::new(bus, cycle, health, 1000, 100_000);
        // Not a real-time thread: a late reply is this host's doing, not a lost frame.
        engine.set_late_reply(LateReply::WAIT);
        tx.send(ends).unwrap();
        let mut clock = CycleClock::start(1_000_000);
        // Warm-up: first-use initialisation (thread-locals of the executor) happens here.
        for _ in 0..200 {
            engine.step(clock.wait());
        }
        // The counter counts: one allocation while watching is seen.
        counting::watch(true);
        std::hint::black_box(vec![1u8; 16]);
        counting::watch(false);
        assert_eq!(counting::take_count(), 1, "the counting allocator works");
        counting::watch(true);
        for _ in 0..3000 {
            engine.step(clock.wait());
        }
        counting::watch(false);
        (counting::take_count(), engine.figures())
    });
    let ends = rx.recv().unwrap();
    let names = (0..4).map(|i| format!("a{i}")).collect();
    let ctl = Controller::new(ends, names);
    for i in 0..4 {
        ctl.command(i, Command::Power(PowerCommand::Enable))
            .unwrap();
        let home = Command::SetPosition {
            position: 0.0,
            relative: false,
        };
        ctl.command(i, home).unwrap();
    }
    std::thread::sleep(Duration::from_millis(300));
    let mut done = 0;
    for round in 0..8 {
        let handles: Vec<_> = (0..4)
            .map(|i| {
                let to = if round % 2 == 0 { 10.0 } else { 0.0 };
                let m = MovePtp::new(PositioningMode::AbsNormal, to);
                ctl.command(i, Command::MovePtp(m)).unwrap()
            })
            .collect();
        for h in handles {
            if h.wait(Duration::from_secs(2)).is_ok() {
                done += 1;
            }
        }
        // A reset of an axis that has no error is also a request the cycle serves.
        ctl.reset(round % 4).unwrap();
    }
    let (allocations, figures) = cycle_thread.join().unwrap();
    eprintln!(
        "cycle thread: {allocations} allocations in 3000 cycles; {done} moves done; wake-up {}; compute {}; round trip {}",
        figures.wake, figures.compute, figures.round_trip
    );
    assert!(done >= 16, "the moves ran while we counted: {done}");
    assert_eq!(allocations, 0);
}
