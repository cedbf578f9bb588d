//! The CANopen bus' bring-up on simulated CiA 402 nodes in lockstep at 1 Mbit/s: NMT reset
//! communication and every node's boot-up, identity read by SDO, PDOs mapped by SDO in
//! pre-operational (read back from the simulated nodes' dictionaries, which enforce
//! CiA 301's rules on every write), heartbeat and cycle period set, NMT start; a node
//! that does not boot is named; a configuration whose frames do not fit the bit rate is
//! refused with the figure.

use gantry::canopen::pdo::DrivePlan;
use gantry::runtime::bus::CycleBus;
use gantry_drives::cia402::pdo::PdoLayout;
use gantry_sim::canopen::nmt::NmtSlaveState;
use gantry_tests::can_rig::{can_config, servos, CanRig};

/// `index:sub` of `node` as its SDO server reads it, little-endian into a u32.
fn read(rig: &CanRig, node: u8, index: u16, sub: u8) -> u32 {
    rig.read_u32(node, index, sub)
}

#[test]
fn every_node_boots_is_identified_mapped_and_started() {
    let ids = [3, 7, 12, 5];
    let config = can_config(&ids, 2000, "csp");
    let rig = CanRig::new(&config, servos(&ids));
    assert!(
        rig.log
            .contains("CANopen: 4 nodes booted after NMT reset communication"),
        "{}",
        rig.log
    );
    assert!(
        rig.log
            .contains("node 7 (axis \"a1\"): CiA 402 device type 0x00020192"),
        "{}",
        rig.log
    );
    assert!(
        rig.log
            .contains("node 12: RPDO1 7 bytes, TPDO1 8 bytes, TPDO2 7 bytes"),
        "{}",
        rig.log
    );
    let bus = &rig.engine.bus;
    assert_eq!(bus.drives(), 4);
    let plan = DrivePlan::of(&PdoLayout::csp()).unwrap();
    for (i, &node) in ids.iter().enumerate() {
        assert_eq!(bus.node(i).unwrap().get(), node, "axis i on bus position i");
        let info = bus.node_infos()[i];
        assert_eq!(info.device_type, 0x0002_0192);
        assert_eq!(info.identity[3], Some(u32::from(node)), "serial = node id");
        assert_eq!(rig.sim().node(node).nmt_state(), NmtSlaveState::Operational);
        // The mapping, as the node has it (CiA 301 §7.5.2.35–.38).
        for (comm, mapping, base, pdos) in [
            (0x1400u16, 0x1600u16, 0x200u32, &plan.rpdos),
            (0x1800, 0x1A00, 0x180, &plan.tpdos),
        ] {
            for n in 0..4u16 {
                let cob = read(&rig, node, comm + n, 1);
                let predefined = base + 0x100 * u32::from(n) + u32::from(node);
                match pdos.iter().find(|p| u16::from(p.number) == n + 1) {
                    Some(p) => {
                        assert_eq!(cob, predefined, "node {node} 0x{:04X}:01 valid", comm + n);
                        assert_eq!(read(&rig, node, comm + n, 2), 1, "synchronous every SYNC");
                        let count = read(&rig, node, mapping + n, 0);
                        assert_eq!(count as usize, p.entries.len());
                        let entries: Vec<u32> = (1..=count as u8)
                            .map(|s| read(&rig, node, mapping + n, s))
                            .collect();
                        assert_eq!(entries, p.mapping_values().collect::<Vec<_>>());
                    }
                    None => assert_eq!(
                        cob,
                        (1 << 31) | predefined,
                        "node {node} 0x{:04X}:01 unused PDO invalid",
                        comm + n
                    ),
                }
            }
        }
        assert_eq!(read(&rig, node, 0x1017, 0), 100, "heartbeat 100 ms");
        assert_eq!(read(&rig, node, 0x1006, 0), 2000, "cycle period 2 ms");
    }
    assert!(!bus.any_fault());
}

#[test]
fn the_minimal_layout_maps_one_pdo_each_way_and_sets_csp_by_sdo() {
    let config = can_config(&[1, 2], 1000, "csp-minimal");
    let rig = CanRig::new(&config, servos(&[1, 2]));
    for node in [1, 2] {
        assert_eq!(read(&rig, node, 0x1600, 0), 2);
        assert_eq!(read(&rig, node, 0x1600, 1), 0x607A_0020);
        assert_eq!(read(&rig, node, 0x1600, 2), 0x6040_0010);
        assert_eq!(read(&rig, node, 0x1A00, 1), 0x6064_0020);
        assert_eq!(read(&rig, node, 0x1A00, 2), 0x6041_0010);
        assert_eq!(read(&rig, node, 0x1801, 1) >> 31, 1, "TPDO2 invalid");
        assert_eq!(read(&rig, node, 0x6060, 0), 8, "CSP");
    }
}

#[test]
fn a_node_that_does_not_boot_is_named() {
    // The configuration has nodes 1, 2, 9 and 11; the bus has 1 and 2 only.
    let config = can_config(&[1, 9, 2, 11], 2000, "csp-minimal");
    let e = CanRig::try_new(&config, servos(&[1, 2]))
        .err()
        .expect("bring-up fails");
    assert_eq!(
        e.to_string(),
        "CANopen: no boot-up from nodes 9, 11 within 2000 ms of NMT reset communication \
         (powered? node id? bit rate?)"
    );
}

#[test]
fn a_configuration_whose_frames_do_not_fit_the_bit_rate_is_refused_with_the_figure() {
    let text = |nodes: usize| {
        let mut t = "[bus]\nkind = \"canopen\"\ninterface = \"can0\"\nbitrate = 1000000\n\
                     cycle_us = 1000\n"
            .to_string();
        for i in 0..nodes {
            t += &format!(
                "[[axis]]\nname = \"a{i}\"\nnode = {}\n\
                 scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
                 max = {{ speed = 200.0, acceleration = 2000.0, jerk = 20000.0 }}\n",
                i + 1
            );
        }
        t
    };
    // Two drives with the full CSP layout fit 1 Mbit/s at 1 ms; eight do not.
    assert!(gantry::config::Config::parse(&text(2), "c.toml").is_ok());
    let e = gantry::config::Config::parse(&text(8), "c.toml")
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "c.toml:4: bus.bitrate: 8 drives × 3 PDOs + SYNC at 1 kHz need 3.31 Mbit/s (3141 bits \
         in the 950 µs the cycle waits for its TPDOs, heartbeats included); can0 has 1 Mbit/s"
    );
}
