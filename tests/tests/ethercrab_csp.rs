//! A CiA-402 servo in CSP mode on the simulated bus, driven by ethercrab with gantry's
//! drive layer and motion kernel: the master walks the power state machine with
//! `next_command` until Operation enabled, then streams an S-curve move cycle by cycle;
//! the simulated drive follows with a finite bandwidth. Lockstep: the test advances the
//! drive's time by one cycle per exchange.

use ethercrab::std::ethercat_now;
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage};
use gantry::ethercat::transition;
use gantry_drives::cia402::{next_command, Controlword, State, Statusword, Target};
use gantry_drives::scaling::{Scaling, ScalingConfig};
use gantry_kernel::profile::{plan_position, KinematicState, Limits, RampType};
use gantry_sim::catalog::{INPUTS_AT, OUTPUTS_AT};
use gantry_sim::chain::SlaveChain;
use gantry_sim::esc::sii::DeviceDescription;
use gantry_sim::plant::servo::ServoDrive;
use gantry_sim::plant::DeviceModel;
use gantry_sim::slave::Slave;
use gantry_tests::invariant::{assert_drive_invariants, DriveUnderTest, TestConditions};
use gantry_tests::EmbeddedBus;

const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
static PDU_STORAGE: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();

const DT: f64 = 0.001;

fn servo_description() -> DeviceDescription {
    DeviceDescription {
        order_code: "SIM-SERVO".into(),
        name: "simulated CiA-402 servo".into(),
        ..gantry_tests::eeprom_pdo_device(
            1,
            &[(0x6040, 16), (0x607A, 32)],
            &[(0x6041, 16), (0x6064, 32)],
        )
    }
}

#[test]
fn ethercrab_enables_the_simulated_servo_and_moves_it_in_csp() {
    let servo = ServoDrive::new(OUTPUTS_AT, INPUTS_AT, 12_345);
    let chain = SlaveChain::new(vec![
        Slave::new(servo_description()).with_device(DeviceModel::Servo(servo))
    ]);
    let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().expect("split once");
    let bus = EmbeddedBus::start(tx, rx, chain);
    let chain = bus.chain.clone();
    let maindevice = MainDevice::new(
        pdu_loop,
        gantry_tests::lockstep_timeouts(),
        MainDeviceConfig::default(),
    );
    let result = futures_lite::future::block_on(async {
        let group = maindevice.init_single_group::<8, 64>(ethercat_now).await?;
        let group = transition::into_op(
            group.into_safe_op(&maindevice).await?,
            &maindevice,
            transition::OP_TIMEOUT,
        )
        .await?;
        let sd = group.subdevice(&maindevice, 0)?;
        let mut last_cw = Controlword(0);
        let mut enabled_after = None;
        let mut profile = None;
        let mut t_move = 0.0;
        let mut max_following = 0.0f64;
        let mut target = 0i32;
        for cycle in 0..6000u32 {
            let (sw, actual) = {
                let i = sd.inputs_raw();
                (
                    Statusword(u16::from_le_bytes([i[0], i[1]])),
                    i32::from_le_bytes([i[2], i[3], i[4], i[5]]),
                )
            };
            let state = sw.state();
            if state == Some(State::OperationEnabled) && enabled_after.is_none() {
                enabled_after = Some(cycle);
                let lim = Limits {
                    vmax: 200_000.0,
                    amax: 2_000_000.0,
                    dmax: 2_000_000.0,
                    jmax: 50_000_000.0,
                };
                profile = Some(
                    plan_position(
                        RampType::SCurve,
                        KinematicState::at_rest(f64::from(actual)),
                        112_345.0,
                        0.0,
                        &lim,
                    )
                    .expect("plan"),
                );
            }
            let cmd = next_command(
                state.unwrap_or(State::NotReadyToSwitchOn),
                Target::Enabled,
                true,
                last_cw,
            );
            last_cw = Controlword::of(cmd);
            target = match &profile {
                Some(p) => {
                    t_move += DT;
                    p.sample(t_move).p.round() as i32
                }
                None => actual,
            };
            if profile.is_some() {
                max_following = max_following.max(f64::from(target - actual).abs());
            }
            {
                let mut io = sd.io_raw_mut();
                let o = io.outputs();
                o[0..2].copy_from_slice(&last_cw.0.to_le_bytes());
                o[2..6].copy_from_slice(&target.to_le_bytes());
            }
            group.tx_rx(&maindevice).await?;
            chain.lock().unwrap().tick(DT);
        }
        let i = sd.inputs_raw();
        let final_actual = i32::from_le_bytes([i[2], i[3], i[4], i[5]]);
        let final_state = Statusword(u16::from_le_bytes([i[0], i[1]])).state();
        Ok::<_, ethercrab::error::Error>((
            enabled_after,
            final_actual,
            final_state,
            max_following,
            target,
        ))
    });
    // The drive's own record: the streamed profile (200 000 counts/s) never stepped more
    // than vmax · T + 1 count, and the drive never faulted on its following error.
    let drives = [DriveUnderTest {
        axis: "profile".into(),
        slave: 0,
        vmax: 200_000.0,
        scaling: Scaling::new(ScalingConfig {
            counts_per_motor_rev: 1,
            motor_revs: 1,
            load_revs: 1,
            units_per_load_rev: 1.0,
            invert: false,
        })
        .unwrap(),
    }];
    assert_drive_invariants(
        &chain.lock().unwrap(),
        &drives,
        DT,
        // One exchange, then one drive cycle: no setpoint may be missed or doubled.
        TestConditions {
            phase_locked: true,
            ..TestConditions::default()
        },
    );
    bus.stop();
    let (enabled_after, final_actual, final_state, max_following, target) =
        result.expect("CSP run");
    let enabled_after = enabled_after.expect("the drive reached Operation enabled");
    // Three transitions (2, 3, 4), each seen two cycles later: the drive acts on outputs
    // after the exchange, and its new statusword travels back with the next one.
    assert!(enabled_after <= 10, "enabled after {enabled_after} cycles");
    assert_eq!(final_state, Some(State::OperationEnabled));
    assert_eq!(target, 112_345);
    assert!(
        (final_actual - 112_345).abs() <= 1,
        "ends on target: {final_actual}"
    );
    // Seen by the master, the actual position trails the set position by the loop's lag,
    // v / (2π·200 Hz) ≈ 160 counts at 200 000 counts/s, plus two cycles of transport
    // (2 ms · v = 400 counts): at most ≈ 560 counts at full speed.
    assert!(
        max_following > 200.0 && max_following < 700.0,
        "following error {max_following}"
    );
}
