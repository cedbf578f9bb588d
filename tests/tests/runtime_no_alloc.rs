//! The cycle thread allocates nothing, in the configuration `gantry run` uses: the cycle
//! thread started as `gantry run` starts it (`service::start_cycle`: SCHED_FIFO 80, memory
//! locked, the bus brought up from it, late replies lost at the deadline), then
//! `Engine::run` — its clock, the phase lock to SYNC0 the simulated servos' distributed
//! clocks switch on, the shutdown at the end. A counting allocator watches the cycle
//! thread from its first cycle to its last while the application moves the axes, the bus
//! loses frames, a cable is pulled long enough for a slave to drop out of OP, and a reset
//! brings it back (the recovery's register accesses run inside the watched cycles), and
//! SDO transfers (expedited and segmented, both ways, 64 KiB each way, an abort) go
//! through the drives' mailboxes beside the process data. That
//! it takes no lock is `runtime_no_lock.rs`. Needs root (real time), as `deploy/test.sh`
//! runs it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::Duration;

use gantry::runtime::controller::Controller;
use gantry::runtime::sdo::{SdoData, SdoRequest, SDO_MAX_BYTES};
use gantry::service::{start_cycle, CYCLE_STACK_BYTES, CYCLE_THREAD};
use gantry_cli::simulator::{SimLink, Simulator};
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;

mod counting {
    include!("../../kernel/tests/common/counting_alloc.rs");
}

#[global_allocator]
static ALLOC: counting::Counting = counting::Counting;

const AXES: usize = 4;

#[test]
fn the_cycle_thread_does_not_allocate_in_production_configuration() {
    let mut config = gantry_tests::sim_config(AXES, 1000);
    // This test is about the cycle thread, not about riding through lost frames
    // (`bus_faults`, `claim_*` test the limit): on this project's non-preemptible VMs a
    // real-time thread now and then waits milliseconds, three frames in a row are lost
    // and the example's limit would stop the axes it exercises.
    config.bus.faults.lost_frames_limit = 50;
    gantry::runtime::rt::check(&config.rt, false).expect("this test needs root (SCHED_FIFO)");
    let drives = gantry_tests::invariant::DriveUnderTest::of_config(&config);
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel();
    let cycle_stop = stop.clone();
    let cycle_thread = std::thread::Builder::new()
        .name(CYCLE_THREAD.into())
        .stack_size(CYCLE_STACK_BYTES)
        .spawn(move || {
            let simulator = Simulator::new(SimLink::Thread);
            let (engine, ends) =
                start_cycle(&config, true, &simulator, &mut std::io::sink()).unwrap();
            assert!(
                engine.bus().ethercat().is_some_and(|b| b.dc().active),
                "SYNC0 runs: Engine::run phase-locks"
            );
            tx.send((ends, simulator.chain().unwrap())).unwrap();
            // The counter counts: one allocation while watching is seen.
            counting::watch(true);
            std::hint::black_box(vec![1u8; 16]);
            counting::watch(false);
            assert_eq!(counting::take_count(), 1, "the counting allocator works");
            counting::watch(true);
            let engine = engine.run(1_000_000, &cycle_stop);
            counting::watch(false);
            let allocations = counting::take_count();
            let lost = gantry::runtime::bus::CycleBus::counters(&engine.bus).lost;
            (allocations, engine.counters().cycles, lost)
        })
        .unwrap();
    let (ends, chain) = rx.recv().unwrap();
    // An object longer than a drive's mailbox carries in one message: segmented both ways
    // (0x2E00: free on the simulated servo, whose 0x2100 is its commutation offset).
    let long: Vec<u8> = (0..200u32).map(|i| i as u8).collect();
    // And one of the most a transfer carries (64 KiB: 555 mailbox messages each way).
    let big: Vec<u8> = (0..SDO_MAX_BYTES)
        .map(|i| (i / 3) as u8 ^ (i >> 11) as u8)
        .collect();
    for i in 0..AXES {
        let mut c = chain.lock().unwrap();
        let od = c.slave_mut(i).and_then(|s| s.object_dictionary_mut());
        let od = od.expect("a servo with CoE");
        od.insert(0x2E00, 0, &long, true);
        od.insert(0x2E03, 0, &big, true);
    }
    let names = (0..AXES).map(|i| format!("a{i}")).collect();
    let ctl = Controller::new(ends, names);
    // SDO transfers during a move, each waited for.
    let transfers = |round: usize| {
        let drive = round % AXES;
        let new: Vec<u8> = long.iter().map(|b| b ^ round as u8).collect();
        let requests = [
            SdoRequest::upload(drive, 0x1018, 1),
            SdoRequest::download(drive, 0x6060, 0, SdoData::new(&[8])),
            SdoRequest::download(drive, 0x2E00, 0, SdoData::new(&new)),
            SdoRequest::upload(drive, 0x2E00, 0),
            SdoRequest::upload(drive, 0x2000, 0),
        ];
        let mut outcomes = Vec::new();
        for r in requests {
            let h = ctl.sdo(r).unwrap();
            outcomes.push(h.wait(Duration::from_secs(5)).expect("an outcome"));
        }
        assert!(outcomes[..3].iter().all(Result::is_ok), "{outcomes:?}");
        assert_eq!(outcomes[3].as_ref().unwrap().as_slice(), &new[..]);
        assert!(outcomes[4].is_err(), "0x2000 does not exist: aborted");
        if round == 0 {
            // 64 KiB up, then down, every byte checked at both ends.
            let h = ctl.sdo(SdoRequest::upload(drive, 0x2E03, 0)).unwrap();
            let up = h.wait(Duration::from_secs(60)).expect("an outcome");
            assert!(
                up.as_ref().is_ok_and(|d| d.as_slice() == &big[..]),
                "{up:?}"
            );
            let back: Vec<u8> = big.iter().map(|b| !b).collect();
            let request = SdoRequest::download(drive, 0x2E03, 0, SdoData::new(&back));
            let h = ctl.sdo(request).unwrap();
            assert_eq!(h.wait(Duration::from_secs(60)), Ok(Ok(SdoData::EMPTY)));
            let c = chain.lock().unwrap();
            let od = c.slaves()[drive].object_dictionary().unwrap();
            assert!(
                od.read(0x2E03, 0).unwrap() == &back[..],
                "what reached the drive"
            );
        }
    };
    for i in 0..AXES {
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
    // What a move that did not finish saw: its status and the axis.
    let mut missed = Vec::new();
    let mut note = |i: usize, outcome: String, ctl: &Controller| {
        let axis = &ctl.snapshot().axes[i];
        missed.push(format!(
            "a{i}: {outcome}, {:?} error {:?} at cycle {}",
            axis.state,
            axis.error,
            ctl.snapshot().cycle
        ));
    };
    let moves = |to: f64| -> Vec<_> {
        (0..AXES)
            .map(|i| {
                let m = MovePtp::new(PositioningMode::AbsNormal, to);
                ctl.command(i, Command::MovePtp(m)).unwrap()
            })
            .collect()
    };
    for round in 0..4 {
        let handles = moves(if round % 2 == 0 { 10.0 } else { 0.0 });
        if round == 1 {
            // Two frames lost mid-move (fewer in a row than the limit: ridden through).
            chain.lock().unwrap().drop_frames(2);
        }
        transfers(round);
        for (i, h) in handles.into_iter().enumerate() {
            match h.wait(Duration::from_secs(2)) {
                Ok(CommandStatus::Done) => done += 1,
                other => note(i, format!("round {round}: {other:?}"), &ctl),
            }
        }
        // A reset of an axis without error is served too.
        ctl.reset(round % AXES).unwrap();
    }
    // The cable behind drive 1 pulled for longer than the slaves' watchdog: drives 2
    // and 3 drop to SafeOp with an error; plugged back, their resets bring them back to
    // OP, one register access per cycle, inside the watched cycles.
    chain.lock().unwrap().cut_before(Some(2));
    std::thread::sleep(Duration::from_millis(300));
    chain.lock().unwrap().cut_before(None);
    std::thread::sleep(Duration::from_millis(20));
    assert_eq!(chain.lock().unwrap().slaves()[2].al_status(), 0x14);
    let resets: Vec<_> = (2..AXES).map(|i| ctl.reset(i).unwrap()).collect();
    for r in &resets {
        assert_eq!(r.wait(Duration::from_secs(5)), Ok(CommandStatus::Done));
    }
    assert_eq!(chain.lock().unwrap().slaves()[2].al_status(), 0x08);
    for i in 2..AXES {
        ctl.command(i, Command::Power(PowerCommand::Enable))
            .unwrap();
    }
    std::thread::sleep(Duration::from_millis(200));
    for (i, h) in moves(5.0).into_iter().enumerate() {
        match h.wait(Duration::from_secs(2)) {
            Ok(CommandStatus::Done) => done += 1,
            other => note(i, format!("after the resets: {other:?}"), &ctl),
        }
    }
    stop.store(true, Ordering::Relaxed);
    let (allocations, cycles, lost) = cycle_thread.join().unwrap();
    // The percentiles are the application's work: from every cycle's durations.
    let figures = ctl.figures();
    eprintln!(
        "cycle thread: {allocations} allocations in {} cycles (Engine::run, SCHED_FIFO, \
         late replies lost); {done} moves done; {lost} frames lost; wake-up {}; compute {}; \
         round trip {}",
        figures.cycles, figures.wake, figures.compute, figures.round_trip
    );
    // About 2 s of cycles; a loaded host skips some (overruns).
    assert!(cycles > 1000, "{cycles} cycles watched");
    assert_eq!(figures.cycles, cycles);
    assert_eq!(
        figures.wake.count, cycles,
        "every cycle's durations reached the application"
    );
    assert!(lost >= 2, "the dropped frames were lost: {lost}");
    let records = gantry_tests::invariant::records(&chain.lock().unwrap());
    assert!(
        done >= 4,
        "moves ran while we counted: {done}; {missed:#?}; drives: {records:#?}"
    );
    // The frames were dropped by the test and the host is not real time: setpoints may be
    // missed, never stepped beyond the axis' speed.
    let conditions = gantry_tests::invariant::TestConditions::default();
    if let Err(e) = gantry_tests::invariant::check_records(&records, &drives, 1e-3, conditions) {
        panic!("{e}");
    }
    assert_eq!(allocations, 0);
}
