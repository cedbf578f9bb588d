//! PDO mapping from the configuration, lockstep: in PreOp the master writes a layout
//! (controlword, target, mode / statusword, position, velocity, torque, error code, mode
//! display) into each simulated servo's mapping objects by SDO; ethercrab sizes the
//! process image from them; the servo exchanges exactly that; and the drive's error code
//! reaches the axis error text. A layout the drive cannot map is refused with the SDO
//! abort, by object.

use ethercrab::std::ethercat_now;
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage};
use gantry::axis_fault::describe_fault;
use gantry::ethercat::mapping::map_pdos;
use gantry::ethercat::transition;
use gantry::runtime::cycle::Cycle;
use gantry_drives::cia402::objects;
use gantry_drives::cia402::pdo::PdoLayout;
use gantry_drives::csp::CspChannel;
use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::{AxisConfig, AxisKind, Kernel};
use gantry_tests::lockstep::Lockstep;
use gantry_tests::{ball_screw_5mm, servo_chain};

const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
static PDU_STORAGE: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();

#[test]
fn the_master_maps_pdos_in_preop_and_the_drives_exchange_them() {
    let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().unwrap();
    let mut net = Lockstep::new(tx, rx, servo_chain(2));
    let md = MainDevice::new(
        pdu_loop,
        gantry_tests::lockstep_timeouts(),
        MainDeviceConfig::default(),
    );
    let group = net
        .block_on(md.init_single_group::<4, 128>(ethercat_now))
        .unwrap();
    let layout = PdoLayout::csp();

    // A mistake first: torque actual in the outputs is refused, by object and abort.
    let mut wrong = layout.clone();
    wrong.outputs.push(objects::TORQUE_ACTUAL_VALUE);
    let sd = group.subdevice(&md, 1).unwrap();
    let e = net.block_on(map_pdos(&sd, &wrong)).unwrap_err();
    let text = e.to_string();
    assert!(
        text.starts_with("slave 0x1001: SDO download 0x1600:04 = 60770010 refused"),
        "{text}"
    );
    assert!(
        text.contains("0x06040041") || text.to_lowercase().contains("mapped"),
        "{text}"
    );

    for i in 0..2 {
        let sd = group.subdevice(&md, i).unwrap();
        net.block_on(map_pdos(&sd, &layout)).unwrap();
    }
    let group = net
        .block_on(async {
            transition::into_op(group.into_safe_op(&md).await?, &md, transition::OP_TIMEOUT).await
        })
        .unwrap();
    for i in 0..2 {
        let sd = group.subdevice(&md, i).unwrap();
        assert_eq!(sd.outputs_raw().len(), layout.output_bytes());
        assert_eq!(sd.inputs_raw().len(), layout.input_bytes());
    }

    let axes = vec![
        AxisConfig::new("x", AxisKind::Real),
        AxisConfig::new("y", AxisKind::Real),
    ];
    let channels = (0..2)
        .map(|_| CspChannel::with_layout(ball_screw_5mm(), &layout).unwrap())
        .collect();
    let mut c = Cycle::new(Kernel::new(1e-3, axes).unwrap(), channels);
    for i in 0..2 {
        c.kernel
            .command(i, Command::Power(PowerCommand::Enable))
            .unwrap();
    }
    let cycle = |net: &mut Lockstep, c: &mut Cycle| {
        for i in 0..2 {
            let sd = group.subdevice(&md, i).unwrap();
            c.read_inputs(i, &sd.inputs_raw()).unwrap();
        }
        c.step();
        for i in 0..2 {
            let sd = group.subdevice(&md, i).unwrap();
            c.write_outputs(i, sd.io_raw_mut().outputs()).unwrap();
        }
        net.block_on(group.tx_rx(&md)).unwrap();
        net.chain.tick(1e-3);
    };
    for _ in 0..20 {
        cycle(&mut net, &mut c);
    }
    assert_eq!(
        c.kernel.axis_status(0).unwrap().state,
        AxisState::Standstill
    );
    // The mode the master wrote is displayed back.
    let sd = group.subdevice(&md, 0).unwrap();
    assert_eq!(sd.inputs_raw()[layout.input_offset(0x6061).unwrap()], 8);

    // Silence the master past the watchdog: the drive faults with 0x8700, and the axis
    // error says so in words (the error code is in the process data now).
    for _ in 0..150 {
        net.chain.tick(1e-3);
    }
    for _ in 0..3 {
        cycle(&mut net, &mut c);
    }
    let error = c.kernel.axis_status(0).unwrap().error.unwrap();
    assert!(
        describe_fault(&error).starts_with("drive fault 0x8700: sync controller error"),
        "{}",
        describe_fault(&error)
    );
}
