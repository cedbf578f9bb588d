//! Distributed clocks through gantry's own bring-up: with the simulated servos (which have
//! DC), `EthercatBus` configures SYNC0 at the cycle time; the engine exchanges with
//! `tx_rx_dc` every cycle (the reference clock's time goes to the others); the slaves
//! pulse SYNC0 once per cycle (in lockstep: exactly once) and their system times agree; the snapshot reports where
//! in the SYNC0 period the frames arrive.

use gantry_tests::rig::Rig;

#[test]
fn gantry_runs_the_bus_with_sync0_at_the_cycle_time() {
    let mut log = Vec::new();
    let mut rig = Rig::logged(&gantry_tests::sim_config_strict(3, 1000), &mut log);
    let log = String::from_utf8(log).unwrap();
    assert!(
        log.contains("distributed clocks: SYNC0 every 1000 µs"),
        "{log}"
    );
    assert!(rig.engine.bus.dc().active);
    // SYNC0 starts 100 ms after configuration; then count pulses over 1000 cycles.
    rig.run(300);
    let pulses = |c: &gantry_sim::chain::SlaveChain| -> Vec<u64> {
        c.slaves().iter().map(|s| s.sync0_events()).collect()
    };
    let before = pulses(&rig.chain.lock().unwrap());
    rig.run(1000);
    let c = rig.chain.lock().unwrap();
    let after = pulses(&c);
    let now = c.now_ns();
    let times: Vec<u64> = c
        .slaves()
        .iter()
        .map(|s| s.dc_system_time(now).unwrap())
        .collect();
    drop(c);
    let snapshot = rig.snapshot();
    let counted: Vec<u64> = after.iter().zip(&before).map(|(a, b)| a - b).collect();
    assert_eq!(counted, [1000; 3], "SYNC0 pulses in 1000 cycles");
    let spread = times.iter().max().unwrap() - times.iter().min().unwrap();
    let offset = snapshot.dc_offset_ns.expect("the snapshot reports DC");
    eprintln!(
        "system time spread {spread} ns; frames {} µs into the SYNC0 period",
        offset as f64 / 1000.0
    );
    assert!(spread < 5_000, "slaves agree on system time: {spread} ns");
    // The cycle holds its frames a quarter period after SYNC0 (the phase lock's target).
    assert!(
        (240_000..=260_000).contains(&offset),
        "frames {offset} ns into the SYNC0 period"
    );
}
