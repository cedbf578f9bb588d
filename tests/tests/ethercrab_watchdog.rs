//! The process-data watchdog, lockstep in one thread: a servo in OP, enabled, keeps
//! running while the master sends every cycle; when the master falls silent for longer
//! than the watchdog time (100 ms by default), the slave leaves OP with AL status code
//! 0x001B and the drive faults; the master then brings it back (acknowledge, OP, fault
//! reset, enable) and it moves again.

use ethercrab::std::ethercat_now;
use ethercrab::subdevice_group::Op;
use ethercrab::{AlStatusCode, MainDevice, MainDeviceConfig, PduStorage, SubDeviceGroup};
use gantry::ethercat::transition;
use gantry::runtime::cycle::Cycle;
use gantry_drives::cia402::State;
use gantry_drives::csp::CspChannel;
use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::{AxisConfig, AxisKind, Kernel};
use gantry_sim::catalog::{self, ServoOptions};
use gantry_sim::chain::SlaveChain;
use gantry_sim::plant::servo::ERROR_SYNC_WATCHDOG;
use gantry_sim::plant::DeviceModel;
use gantry_tests::ball_screw_5mm;
use gantry_tests::lockstep::Lockstep;

const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
static PDU_STORAGE: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();

/// AL control register and the bits a master writes to it.
const AL_CONTROL: u16 = 0x0120;
const AL_OP_WITH_ACK: u16 = 0x08 | 0x10;

type Group = SubDeviceGroup<2, 64, ethercrab::DefaultLock, Op>;

fn cycle(net: &mut Lockstep, md: &MainDevice<'static>, group: &Group, c: &mut Cycle) {
    let sd = group.subdevice(md, 0).unwrap();
    c.read_inputs(0, &sd.inputs_raw()).unwrap();
    c.step();
    c.write_outputs(0, sd.io_raw_mut().outputs()).unwrap();
    net.block_on(group.tx_rx(md)).unwrap();
    net.chain.tick(1e-3);
}

fn servo_state(net: &Lockstep) -> (State, u16) {
    match net.chain.slaves()[0].device() {
        DeviceModel::Servo(s) => (s.state(), s.error_code()),
        _ => unreachable!(),
    }
}

#[test]
fn silent_master_trips_the_watchdog_and_the_master_recovers() {
    let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().unwrap();
    let chain = SlaveChain::new(vec![catalog::servo(ServoOptions::default())]);
    let mut net = Lockstep::new(tx, rx, chain);
    let md = MainDevice::new(
        pdu_loop,
        gantry_tests::lockstep_timeouts(),
        MainDeviceConfig::default(),
    );
    let group = net
        .block_on(md.init_single_group::<2, 64>(ethercat_now))
        .unwrap();
    let group: Group = net
        .block_on(async {
            transition::into_op(group.into_safe_op(&md).await?, &md, transition::OP_TIMEOUT).await
        })
        .unwrap();
    let kernel = Kernel::new(1e-3, vec![AxisConfig::new("x", AxisKind::Real)]).unwrap();
    let mut c = Cycle::new(kernel, vec![CspChannel::new(ball_screw_5mm())]);
    c.kernel
        .command(0, Command::Power(PowerCommand::Enable))
        .unwrap();

    // Exchanging every 1 ms for 2 s: the watchdog never trips.
    for _ in 0..2000 {
        cycle(&mut net, &md, &group, &mut c);
    }
    assert_eq!(servo_state(&net).0, State::OperationEnabled);
    assert_eq!(net.chain.slaves()[0].al_status(), 0x08);

    // Silent for 99 ms (the last cycle already ran 1 ms after its frame): still fine.
    // Silent for 100 ms: out of OP, drive faulted.
    for _ in 0..98 {
        net.chain.tick(1e-3);
    }
    assert_eq!(net.chain.slaves()[0].al_status(), 0x08, "not before 100 ms");
    for _ in 0..2 {
        net.chain.tick(1e-3);
    }
    // ethercrab reports the flagged AL status code as the error of the status read.
    let status = net.block_on(group.subdevice(&md, 0).unwrap().status());
    assert!(
        matches!(
            status,
            Err(ethercrab::error::Error::SubDevice(
                AlStatusCode::SyncManagerWatchdog
            ))
        ),
        "{status:?}"
    );
    assert_eq!(net.chain.slaves()[0].al_status(), 0x14, "SafeOp + error");
    assert_eq!(servo_state(&net), (State::Fault, ERROR_SYNC_WATCHDOG));
    // The master sees the fault in the statusword, and the kernel stops the axis.
    for _ in 0..3 {
        cycle(&mut net, &md, &group, &mut c);
    }
    assert_eq!(c.inputs(0).unwrap().statusword.state(), Some(State::Fault));
    assert_eq!(c.kernel.axis_status(0).unwrap().state, AxisState::ErrorStop);

    // Recovery: acknowledge and request OP, reset the drive fault, enable again.
    let sd = group.subdevice(&md, 0).unwrap();
    net.block_on(sd.register_write(AL_CONTROL, AL_OP_WITH_ACK))
        .unwrap();
    // The error is acknowledged at once; Op takes the firmware's 5 ms and fresh outputs
    // (leaving Op invalidated the old ones), which the cycles bring.
    assert_eq!(
        net.chain.slaves()[0].al_status(),
        0x04,
        "acknowledged, on its way"
    );
    let mut cycles_to_op = 0;
    while net.chain.slaves()[0].al_status() != 0x08 && cycles_to_op < 20 {
        cycle(&mut net, &md, &group, &mut c);
        cycles_to_op += 1;
    }
    assert_eq!(net.chain.slaves()[0].al_status(), 0x08, "back in OP");
    assert!(
        (5..=6).contains(&cycles_to_op),
        "{cycles_to_op} cycles of 1 ms"
    );
    // MC_Reset: the kernel asks for the drive's fault reset and waits for it.
    let reset = c.kernel.command(0, Command::Reset).unwrap();
    for _ in 0..20 {
        cycle(&mut net, &md, &group, &mut c);
    }
    assert_eq!(c.kernel.command_status(reset), CommandStatus::Done);
    assert_eq!(c.kernel.axis_status(0).unwrap().state, AxisState::Disabled);
    c.kernel
        .command(0, Command::Power(PowerCommand::Enable))
        .unwrap();
    for _ in 0..20 {
        cycle(&mut net, &md, &group, &mut c);
    }
    assert_eq!(servo_state(&net), (State::OperationEnabled, 0));
    assert_eq!(
        c.kernel.axis_status(0).unwrap().state,
        AxisState::Standstill
    );
}
