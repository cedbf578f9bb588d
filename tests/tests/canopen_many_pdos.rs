//! More than four PDOs a direction on a CANopen drive, lockstep on the in-memory bus at
//! 1 Mbit/s: the full `csp` layout with the drive's switches and both touch probes (9
//! output bytes, 37 input bytes: 2 RPDOs and 5 TPDOs) on simulated servos with eight PDOs
//! each way (`pdo_count = 8`). TPDO5 has no predefined COB-ID (CiA 301 stops at four):
//! gantry lends it one of a node id the bus leaves free, maps it by SDO in
//! pre-operational and reads it every cycle. Judged by the homing scenario of EtherCAT
//! (switches, a limit-switch stop, MoveHome latching the touch probe), by moves with no
//! TPDO lost, and by the COB-IDs the simulated nodes hold, unique on the bus; TPDO5
//! alone missing is a lost frame. A drive with four PDOs is refused naming the figure
//! (asked by SDO, or by its EDS at load), and so is a device outside the configuration
//! at a node id that lent an identifier.

use std::path::PathBuf;

use gantry::runtime::bus::CycleBus;
use gantry_drives::canopen::NodeId;
use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_sim::canopen::{CanNode, CanNodeConfig};
use gantry_sim::config::{SimConfig, SlaveConfig};
use gantry_tests::can_rig::{can_config_axes, can_config_text, servos, servos_with_pdos, CanRig};
use gantry_tests::homing::{scenario, servo_switches_toml, AXIS_SWITCHES_TOML};
use gantry_tests::servo_rig::CanopenServo;

/// `index:sub` of `node` as its SDO server reads it, a u32.
fn read(rig: &CanRig, node: u8, index: u16, sub: u8) -> u32 {
    rig.read_u32(node, index, sub)
}

/// The valid PDOs of `node` (of its eight each way): (communication index, COB-ID).
fn valid_pdos(rig: &CanRig, node: u8) -> Vec<(u16, u16)> {
    (0..8u16)
        .flat_map(|n| [0x1400 + n, 0x1800 + n])
        .filter_map(|index| {
            let cob = read(rig, node, index, 1);
            (cob >> 31 == 0).then_some((index, (cob & 0x7FF) as u16))
        })
        .collect()
}

/// The full CSP layout with the drive's switches and probes on `nodes`, 2 ms.
fn config(nodes: &[u8]) -> gantry::config::Config {
    can_config_axes(nodes, 2000, "csp", "", AXIS_SWITCHES_TOML)
}

#[test]
fn the_full_csp_layout_with_switches_and_probes_homes_over_five_tpdos() {
    const NODE: u8 = 5;
    let chain = SimConfig::parse(
        &format!(
            "[[slave]]\nkind = \"servo\"\nnode = {NODE}\npdo_count = 8\n{}",
            servo_switches_toml()
        ),
        "sim.toml",
    )
    .expect("chain");
    let SlaveConfig::Servo(servo) = &chain.slaves[0] else {
        panic!("a servo");
    };
    assert_eq!(servo.pdo_count, 8);
    let node = CanNode::new(CanNodeConfig::from_servo(
        NodeId::new(NODE).expect("node id"),
        servo,
    ))
    .expect("node");
    let rig = CanRig::new(&config(&[NODE]), vec![node]);
    assert!(
        rig.log.contains(
            "node 5: RPDO1 8 bytes, RPDO2 1 bytes, TPDO1 8 bytes, TPDO2 8 bytes, TPDO3 8 bytes, \
             TPDO4 8 bytes, TPDO5 5 bytes on 0x1FE"
        ),
        "{}",
        rig.log
    );
    // TPDO5 as the node holds it: valid on 0x1FE (TPDO1 of node 126, which the bus does
    // not have; gantry is 127), synchronous, the plan's mapping.
    let plan = rig.engine.bus.plan(0).expect("a plan").clone();
    let tpdo5 = &plan.tpdos[4];
    assert_eq!((tpdo5.number, tpdo5.cob_id), (5, 0x1FE));
    assert_eq!(read(&rig, NODE, 0x1804, 1), 0x1FE);
    assert_eq!(read(&rig, NODE, 0x1804, 2), 1);
    let entries: Vec<u32> = (1..=read(&rig, NODE, 0x1A04, 0) as u8)
        .map(|s| read(&rig, NODE, 0x1A04, s))
        .collect();
    assert_eq!(entries, tpdo5.mapping_values().collect::<Vec<_>>());
    let mut rig = CanopenServo {
        rig,
        node: NODE,
        cycle_s: 2e-3,
    };
    assert_eq!(
        gantry_tests::homing::HomingRig::run_command(
            &mut rig,
            Command::Power(PowerCommand::Enable),
            5000
        ),
        CommandStatus::Done
    );
    scenario(&mut rig);
    let bus = &rig.rig.engine.bus;
    assert_eq!(bus.counters().lost, 0, "every TPDO set complete in time");
    assert_eq!(bus.malformed(), 0);
    assert!(bus.exchanges() > 1000, "{} cycles", bus.exchanges());
    let c = rig.rig.sim().node(NODE).counters();
    assert_eq!(c.emcys, 0);
    assert_eq!(c.tpdos % 5, 0, "five TPDOs at each SYNC: {c:?}");
}

#[test]
fn two_drives_with_seven_pdos_move_on_unique_cob_ids_with_no_tpdo_lost() {
    let nodes = [5u8, 6];
    let mut rig = CanRig::new(&config(&nodes), servos_with_pdos(&nodes, 8));
    for axis in 0..nodes.len() {
        rig.enable_and_home(axis);
    }
    for round in [[40.0, -25.0], [-10.0, 60.0]] {
        for (axis, h) in rig.start_moves(&round).iter().enumerate() {
            assert_eq!(
                rig.finish(h, 10_000),
                CommandStatus::Done,
                "axis {axis}: {:?}",
                rig.bus_fault(axis)
            );
        }
        for (axis, &to) in round.iter().enumerate() {
            let counts = (to / 5.0 * 131_072.0_f64).round() as i64;
            let sim = rig.sim();
            let servo = sim.node(nodes[axis]).servo().expect("a servo");
            assert_eq!(i64::from(servo.actual_counts()), counts, "axis {axis}");
        }
    }
    let bus = &rig.engine.bus;
    assert_eq!(bus.counters().lost, 0, "every TPDO in time");
    assert!(!bus.any_fault());
    for &n in &nodes {
        let r = *rig.sim().node(n).servo().expect("a servo").record();
        assert_eq!(
            (r.sync_missed, r.sync_doubled, r.faults),
            (0, 0, 0),
            "{r:?}"
        );
    }
    // The COB-IDs the nodes hold: 2 RPDOs and 5 TPDOs each, TPDO5 on identifiers of
    // node 126 (TPDO1's for node 5, TPDO2's for node 6), every one once on the bus, none
    // another bus node's predefined one.
    let mut all = Vec::new();
    for &n in &nodes {
        let pdos = valid_pdos(&rig, n);
        assert_eq!(pdos.len(), 7, "node {n}: {pdos:?}");
        all.extend(pdos.iter().map(|(_, cob)| *cob));
    }
    assert_eq!(read(&rig, 5, 0x1804, 1), 0x1FE);
    assert_eq!(read(&rig, 6, 0x1804, 1), 0x2FE);
    let mut unique = all.clone();
    unique.sort_unstable();
    unique.dedup();
    assert_eq!(unique.len(), all.len(), "{all:03X?}");
    for &n in &nodes {
        for (index, cob) in valid_pdos(&rig, n) {
            let bits = cob & 0x7F;
            assert!(
                bits == u16::from(n) || !nodes.iter().any(|&m| u16::from(m) == bits),
                "node {n} 0x{index:04X}: 0x{cob:03X} is another node's"
            );
        }
    }
}

#[test]
fn a_drive_with_four_pdos_is_refused_with_the_figure() {
    let e = CanRig::try_new(&config(&[5]), servos(&[5]))
        .err()
        .expect("refused");
    assert_eq!(
        e.to_string(),
        "CANopen node 5 (axis \"a0\"): its process data need 5 TPDOs (37 input bytes in PDOs \
         of 8), the drive has 4 (0x1804:01 does not exist: SDO abort 0x06020000 Object does \
         not exist in the object dictionary.)"
    );
}

#[test]
fn a_device_at_a_node_id_that_lent_its_cob_id_is_named() {
    // Node 126 is on the bus but not in the configuration: TPDO5 of node 5 would share
    // its TPDO1's identifier.
    let mut nodes = servos_with_pdos(&[5], 8);
    nodes.extend(servos(&[126]));
    let e = CanRig::try_new(&config(&[5]), nodes)
        .err()
        .expect("refused");
    assert_eq!(
        e.to_string(),
        "CANopen: node 126 is on the bus (its boot-up came), but gantry gave its predefined \
         COB-ID 0x1FE to TPDO5 of node 5 (axis \"a0\"): add it to the configuration or give it \
         another node id"
    );
}

fn scratch(test: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("gantry-many-pdos-{test}-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("scratch dir");
    d
}

/// With the drive's EDS the count comes from it (`NrOfTXPDO`): the simulator's EDS of a
/// four-PDO servo refuses the layout when the configuration is read, naming the file;
/// that of an eight-PDO servo brings the bus up.
#[test]
fn with_an_eds_the_pdo_count_is_checked_at_load() {
    let d = scratch("eds");
    let with_eds = |file: &str| {
        let mut node = servos_with_pdos(&[5], if file == "four.eds" { 4 } else { 8 }).remove(0);
        let path = d.join(file);
        std::fs::write(&path, gantry_sim::canopen::eds::write(&mut node, file))
            .expect("eds written");
        let axis = format!("eds = \"{}\"\n{AXIS_SWITCHES_TOML}", path.display());
        let text = can_config_text(&[5], 2000, "csp", "", &axis);
        (gantry::config::Config::parse(&text, "can.toml"), path)
    };
    let (refused, four) = with_eds("four.eds");
    let e = refused.expect_err("refused").to_string();
    assert!(
        e.ends_with(&format!(
            "axis[0].eds: CANopen node 5 (axis \"a0\"): its process data need 5 TPDOs (37 \
             input bytes in PDOs of 8), the drive has 4 (NrOfTXPDO in {})",
            four.display()
        )),
        "{e}"
    );
    let (config, _) = with_eds("eight.eds");
    let config = config.unwrap_or_else(|e| panic!("{e}"));
    let rig = CanRig::new(&config, servos_with_pdos(&[5], 8));
    assert!(rig.log.contains("TPDO5 5 bytes on 0x1FE"), "{}", rig.log);
    std::fs::remove_dir_all(&d).expect("scratch removed");
}

/// TPDO5 alone missing (its lent COB-ID 0x1FE no longer reaches gantry) is a lost TPDO
/// set for its drive each cycle: after `lost_frames_limit` (3) in a row the drive is
/// faulted, named; the other drive, whose TPDO5 (0x2FE) still comes, goes on.
#[test]
fn a_missing_fifth_tpdo_is_a_lost_frame() {
    let nodes = [5u8, 6];
    let mut rig = CanRig::new(&config(&nodes), servos_with_pdos(&nodes, 8));
    rig.run(10);
    assert_eq!(rig.engine.bus.counters().lost, 0);
    rig.sim().drop_frames(0x1FE, true);
    rig.run(1);
    let bus = &rig.engine.bus;
    assert_eq!(bus.counters().lost, 1, "{:?}", bus.counters());
    assert_eq!(bus.counters().incomplete, 1, "the other four came");
    assert!(!bus.inputs_fresh(0) && bus.inputs_fresh(1));
    rig.run(2);
    assert_eq!(
        rig.bus_fault(0).as_deref(),
        Some("CANopen node 5: no TPDO for 3 cycles in a row")
    );
    assert_eq!(rig.bus_fault(1), None);
    assert_eq!(rig.engine.bus.can_node(1).map(|s| s.lost_tpdos), Some(0));
}
