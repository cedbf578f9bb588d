//! Digital-input modules (CiA 401) on the CANopen bus: the nodes the axes' switches read
//! (`[axis.switches] X = { from = "module", node = N, input = K }`). Each is brought up
//! with the drives ([`super::bring_up`]: its boot-up, 0x1000 profile 401, heartbeat,
//! NMT start) on its own bus position after theirs, and its TPDO1 is mapped to the
//! 8-bit input groups the switches need (CiA 401 §6: 0x6000:01–08 read input 8-bit, which
//! is also the profile's default TPDO1 mapping) and set synchronous (transmission type 1):
//! its inputs are sampled at each SYNC, with the drives' positions. It has no RPDO (its
//! RPDOs, if any, are left as they are) and only TPDO1 is touched (a CiA 401 device's
//! TPDO2–4 carry analogue inputs, if it has them: left alone, as a digital-only module
//! may not have their objects). The bus then reads it like a drive: a missing TPDO, a
//! silent heartbeat or a boot-up faults it, and with it the axes that read it (the cycle's
//! module switches).

use gantry_drives::canopen::cob_id::NodeId;
use gantry_drives::cia402::objects::{self, DataType, ObjectId};
use gantry_drives::cia402::pdo::PdoLayout;

use super::bring_up::{config_steps_for, CommSettings, DriveSetup, StartError};
use super::load::LoadError;
use super::pdo::DrivePlan;
use crate::config::{Config, ModuleNode};

/// Device profile number of CiA 401 generic I/O modules (0x1000 bits 0–15 = 401).
pub const PROFILE_CIA401: u16 = 401;
/// CiA 401 0x6000 read input 8-bit: sub n is inputs 8(n−1)..8n−1.
pub const READ_INPUT_8: u16 = 0x6000;

/// 0x6000:`group` (1-based), one byte of inputs.
pub const fn read_input_8(group: u8) -> ObjectId {
    ObjectId {
        index: READ_INPUT_8,
        sub: group,
        kind: DataType::U8,
        name: "Read input 8-bit",
    }
}

/// The module's process data: no outputs, 0x6000:01..=`groups` in (input k is then bit
/// `k % 8` of byte `k / 8`, as [`crate::config::ModuleInput::active`] reads it).
pub fn layout(groups: u8) -> PdoLayout {
    PdoLayout {
        outputs: Vec::new(),
        inputs: (1..=groups).map(read_input_8).collect(),
    }
}

/// The PDOs of `module`: TPDO1 with its input groups.
pub fn plan(module: &ModuleNode) -> Result<DrivePlan, LoadError> {
    let layout = layout(module.groups);
    let plan = match NodeId::new(module.node) {
        Ok(node) => DrivePlan::on_node(&layout, node),
        Err(_) => DrivePlan::of(&layout),
    };
    plan.map_err(|source| LoadError::Layout {
        axis: name(module),
        pdo: format!("0x6000:01..={:02X}", module.groups),
        source,
    })
}

/// How messages name `module`.
pub fn name(module: &ModuleNode) -> String {
    format!("I/O module of {}", module.axes.join(", "))
}

/// The bring-up of `module`: its node, layout, PDOs and the SDO writes that configure
/// it — TPDO1's mapping and transmission type by the procedure of CiA 301 §7.5.2.38, the
/// heartbeat producer time, the consumer of gantry's heartbeat, the SYNC counter and the
/// communication cycle period, as for a drive; no RPDO, no mode of operation.
pub fn setup(config: &Config, module: &ModuleNode) -> Result<DriveSetup, StartError> {
    let node = NodeId::new(module.node).map_err(|_| StartError::NoNode { axis: name(module) })?;
    let layout = layout(module.groups);
    let plan = plan(module)?;
    let comm = CommSettings::of(config)?;
    let mut steps = config_steps_for(node, &plan, &layout, &comm, [0, 1]);
    // A CiA 401 device has no 0x6060 (the step is for a drive whose layout lacks it).
    steps.retain(|s| s.mux.index != objects::MODES_OF_OPERATION.index);
    Ok(DriveSetup {
        axis: name(module),
        node,
        profile: PROFILE_CIA401,
        layout,
        plan,
        steps,
        expect: None,
        ask_pdos: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canopen::bring_up::{TPDO_COMMUNICATION, TPDO_MAPPING, TT_SYNC_EVERY};
    use gantry_drives::canopen::sdo::Multiplexer;

    #[test]
    fn tpdo1_maps_the_input_groups_on_sync_and_nothing_else() {
        let config = crate::config::Config::parse(
            "[bus]\nkind = \"canopen\"\ninterface = \"can0\"\nbitrate = 1000000\n\
             cycle_us = 2000\n\
             [[axis]]\nname = \"x\"\nnode = 1\npdo = \"csp-minimal\"\n\
             scaling = { counts_per_motor_rev = 1000, units_per_load_rev = 1.0 }\n\
             max = { speed = 10.0, acceleration = 100.0, jerk = 1000.0 }\n\
             [axis.switches]\nreference = { from = \"module\", node = 9, input = 10 }\n",
            "c.toml",
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let modules = config.module_nodes();
        assert_eq!(modules.len(), 1);
        let m = &modules[0];
        assert_eq!((m.node, m.position, m.groups), (9, 1, 2));
        let s = setup(&config, m).unwrap();
        assert_eq!((s.plan.rpdos.len(), s.plan.tpdos.len()), (0, 1));
        assert_eq!(s.plan.input_bytes, 2);
        let value = |index, sub| {
            s.steps
                .iter()
                .filter(|x| x.mux == Multiplexer::new(index, sub))
                .map(|x| x.value().to_vec())
                .collect::<Vec<_>>()
        };
        // Entries 0x6000:01 and :02, 8 bits each; synchronous; valid on 0x180 + 9.
        assert_eq!(
            value(TPDO_MAPPING, 1),
            [0x6000_0108u32.to_le_bytes().to_vec()]
        );
        assert_eq!(
            value(TPDO_MAPPING, 2),
            [0x6000_0208u32.to_le_bytes().to_vec()]
        );
        assert_eq!(value(TPDO_COMMUNICATION, 2), [vec![TT_SYNC_EVERY]]);
        assert_eq!(
            value(TPDO_COMMUNICATION, 1).last(),
            Some(&0x189u32.to_le_bytes().to_vec())
        );
        // Nothing of the RPDOs, TPDO2–4 or 0x6060.
        assert!(s
            .steps
            .iter()
            .all(|x| !(0x1400..0x1800).contains(&x.mux.index)
                && !(0x1801..0x1A00).contains(&x.mux.index)
                && !(0x1A01..0x1C00).contains(&x.mux.index)
                && x.mux.index != 0x6060));
    }
}
