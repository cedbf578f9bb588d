//! Distributed clocks through gantry's own bring-up: with the simulated servos (which have
//! DC), `EthercatBus` configures SYNC0 at the cycle time; the engine exchanges with
//! `tx_rx_dc` every cycle (the reference clock's time goes to the others); the slaves
//! pulse SYNC0 once per cycle and their system times agree; the snapshot reports where
//! in the SYNC0 period the frames arrive.

use gantry::ethercat::bus::EthercatBus;
use gantry::runtime::clock::CycleClock;
use gantry::runtime::controller::Controller;
use gantry::runtime::engine::{Engine, LateReply};

#[test]
fn gantry_runs_the_bus_with_sync0_at_the_cycle_time() {
    let config = gantry_tests::sim_config(3, 1000);
    let mut log = Vec::new();
    let (bus, cycle, health) = match EthercatBus::bring_up(&config, &mut log) {
        Ok(up) => up,
        Err(e) => panic!("{e}\n{}", String::from_utf8_lossy(&log)),
    };
    let log = String::from_utf8(log).unwrap();
    assert!(
        log.contains("distributed clocks: SYNC0 every 1000 µs"),
        "{log}"
    );
    assert!(bus.dc().active);
    let chain = bus.simulated_chain().unwrap();
    let (mut engine, ends) = Engine::new(bus, cycle, health, 1000, 16);
    // Not a real-time thread: a late reply is this host's doing, not a lost frame.
    engine.set_late_reply(LateReply::WAIT);
    let ctl = Controller::new(ends, vec!["a0".into(), "a1".into(), "a2".into()]);
    let mut clock = CycleClock::start(1_000_000);
    // SYNC0 starts 100 ms after configuration; then count pulses over 1000 cycles.
    for _ in 0..300 {
        engine.step(clock.wait());
    }
    let pulses = |c: &gantry_sim::chain::SlaveChain| -> Vec<u64> {
        c.slaves().iter().map(|s| s.sync0_events()).collect()
    };
    let before = pulses(&chain.lock().unwrap());
    for _ in 0..1000 {
        engine.step(clock.wait());
    }
    let c = chain.lock().unwrap();
    let after = pulses(&c);
    let now = c.now_ns();
    let times: Vec<u64> = c
        .slaves()
        .iter()
        .map(|s| s.dc_system_time(now).unwrap())
        .collect();
    drop(c);
    let snapshot = ctl.snapshot();
    for (b, a) in before.iter().zip(&after) {
        // The simulator runs on the wall clock in this real-time test and the cycle on
        // this non-real-time host: 1000 cycles take 1000 periods only when no cycle
        // overran.
        assert!(
            (900..=1100).contains(&(a - b)),
            "SYNC0 pulses in 1000 cycles: {}",
            a - b
        );
    }
    let spread = times.iter().max().unwrap() - times.iter().min().unwrap();
    eprintln!(
        "SYNC0 pulses in 1000 cycles: {:?}; system time spread {spread} ns; frames {} µs into the SYNC0 period",
        after.iter().zip(&before).map(|(a, b)| a - b).collect::<Vec<_>>(),
        snapshot.dc_offset_ns.unwrap_or(0) as f64 / 1000.0
    );
    assert!(spread < 5_000, "slaves agree on system time: {spread} ns");
    assert!(snapshot.dc_offset_ns.is_some(), "the snapshot reports DC");
}
