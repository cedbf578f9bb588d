//! The commutation measurement (`gantry_drives::commutation`) against the simulated servo
//! in lockstep, through what a master has: the drive's object dictionary (its SDO objects:
//! mode of operation, 0x2101 pole pairs, 0x2102/0x2103 the current vector, 0x2100 the
//! offset) and the position actual value of its process data — never the motor's hidden
//! offset, which only judges the result. One object written per 1 ms cycle, as an SDO
//! transfer takes at least a cycle.

use gantry_drives::cia402::image::{InputImage, OutputImage, PdoMap};
use gantry_drives::cia402::mode::OPEN_LOOP_CURRENT_VECTOR;
use gantry_drives::cia402::objects::{self, ObjectId};
use gantry_drives::cia402::pdo::PdoLayout;
use gantry_drives::cia402::{Controlword, State};
use gantry_drives::commutation::{
    electrical_error_deg, CommutationConfig, CommutationError, CommutationMeasurement,
    CommutationOutcome, Step,
};
use gantry_sim::coe::od::ObjectDictionary;
use gantry_sim::plant::servo::{ServoDrive, ServoParams};

const DT: f64 = 0.001;

/// A servo with the minimal mapping and its dictionary: the master's view.
struct Rig {
    d: ServoDrive,
    od: ObjectDictionary,
    map: PdoMap,
    cw: u16,
    t: f64,
}

impl Rig {
    fn new(params: ServoParams, start: i32) -> Self {
        let mut d = ServoDrive::with_params(0, 0, start, params);
        d.configure(PdoLayout::csp_minimal());
        let mut od = ObjectDictionary::cia402_servo(1, 2, 3, 4);
        d.install_objects(&mut od);
        Self {
            map: PdoMap::of(&PdoLayout::csp_minimal()),
            d,
            od,
            cw: 0,
            t: 0.0,
        }
    }

    /// One cycle: outputs (controlword, target = actual), run, inputs; the position.
    fn cycle(&mut self) -> i32 {
        let mut out = [0u8; 6];
        let here = self.d.actual_counts();
        {
            let mut img = OutputImage::new_checked(&mut out[..], &self.map).unwrap();
            img.set_controlword(Controlword(self.cw));
            img.set_target_position(here);
        }
        self.d.take_output_image(&out);
        self.d.run(DT);
        self.t += DT;
        let mut inp = [0u8; 6];
        self.d.publish_input_image(&mut inp);
        let img = InputImage::new_checked(&inp[..], &self.map).unwrap();
        img.position_actual_value().unwrap()
    }

    /// An SDO download (the dictionary checks access and range), taken by the drive.
    fn write(&mut self, o: ObjectId, v: i64) {
        let bytes = v.to_le_bytes();
        self.od
            .write(o.index, o.sub, &bytes[..o.kind.size()])
            .unwrap_or_else(|e| panic!("{} = {v}: {e:?}", o.name));
        self.d.take_objects(&self.od);
    }

    /// An SDO upload.
    fn read(&mut self, o: ObjectId) -> Vec<u8> {
        self.d.publish_objects(&mut self.od);
        self.od.read(o.index, o.sub).unwrap().to_vec()
    }

    /// Into the open-loop mode, enabled.
    fn enable_open_loop(&mut self) {
        self.write(
            objects::MODES_OF_OPERATION,
            i64::from(OPEN_LOOP_CURRENT_VECTOR),
        );
        for cw in [0x06, 0x07, 0x0F] {
            self.cw = cw;
            self.cycle();
        }
        assert_eq!(self.d.state(), State::OperationEnabled);
    }

    /// Runs a measurement to its end: one write a cycle.
    fn measure(&mut self) -> Result<CommutationOutcome, CommutationError> {
        let pole_pairs = u32::from(self.read(objects::MOTOR_POLE_PAIRS)[0]);
        let config = CommutationConfig::new(self.d.params.counts_per_rev, pole_pairs);
        let mut m = CommutationMeasurement::new(config)?;
        let mut position = self.cycle();
        loop {
            match m.poll(self.t, position) {
                Ok(Step::Write(o, v)) => self.write(o, v),
                Ok(Step::Wait) => {}
                Ok(Step::Done(r)) => return Ok(r),
                Err(e) => {
                    if let Step::Write(o, v) = m.abort() {
                        self.write(o, v);
                    }
                    return Err(e);
                }
            }
            position = self.cycle();
            assert!(self.t < 20.0, "the measurement runs out");
        }
    }
}

/// xorshift64*: seeded, so the 50 cases are the same every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

#[test]
fn fifty_random_offsets_and_pole_pairs_are_measured_within_one_electrical_degree() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut worst: f64 = 0.0;
    let mut most_travel: f64 = 0.0;
    for case in 0..50 {
        let mut params = ServoParams::default();
        params.pole_pairs = 1 + rng.below(64) as u32;
        params.commutation_offset = rng.below(u64::from(params.counts_per_rev)) as i32;
        // A setting the drive was left with, wrong in any way (the measurement does not use
        // the closed loop).
        let start = rng.below(1 << 20) as i32 - (1 << 19);
        let mut r = Rig::new(params, start);
        r.write(objects::COMMUTATION_OFFSET, rng.below(1 << 17) as i64);
        r.enable_open_loop();
        let outcome = r.measure().unwrap_or_else(|e| panic!("case {case}: {e}"));
        let miss = electrical_error_deg(
            i64::from(outcome.offset_counts),
            i64::from(params.commutation_offset),
            params.counts_per_rev,
            params.pole_pairs,
        );
        assert!(
            miss.abs() <= 1.0,
            "case {case}: {} pole pairs, offset {}: measured {outcome:?}, {miss:.3}° el off",
            params.pole_pairs,
            params.commutation_offset
        );
        // Written to the drive, which now commutates right.
        assert_eq!(r.d.commutation_setting, outcome.offset_counts);
        assert!(r.d.torque_efficiency() > 0.9998, "cos 1°");
        // Small motion: about one electrical revolution each way.
        let e = f64::from(params.counts_per_rev) / f64::from(params.pole_pairs);
        most_travel = most_travel.max((r.d.position() - f64::from(start)).abs() / e);
        worst = worst.max(miss.abs());
    }
    assert!(
        most_travel < 1.0,
        "{most_travel} electrical revolutions from the start"
    );
    eprintln!("worst of 50: {worst:.3}° electrical");
}

#[test]
fn the_measured_offset_makes_a_runaway_motor_follow_in_csp() {
    let params = ServoParams {
        pole_pairs: 4,
        // 219.7° electrical from the setting 0: it would run away.
        commutation_offset: 20_000,
        ..ServoParams::default()
    };
    let mut r = Rig::new(params, 0);
    r.enable_open_loop();
    let outcome = r.measure().unwrap();
    // Off again, then CSP: the drive follows a move.
    r.cw = 0x06;
    r.cycle();
    r.write(objects::MODES_OF_OPERATION, 8);
    for cw in [0x07, 0x0F] {
        r.cw = cw;
        r.cycle();
    }
    let from = r.d.actual_counts();
    let mut target = from;
    let mut out = [0u8; 6];
    for _ in 0..500 {
        target += 100;
        {
            let mut img = OutputImage::new_checked(&mut out[..], &r.map).unwrap();
            img.set_controlword(Controlword(0x0F));
            img.set_target_position(target);
        }
        r.d.take_output_image(&out);
        r.d.run(DT);
    }
    assert_eq!(r.d.error_code(), 0, "{outcome:?}");
    assert!((f64::from(target) - r.d.position()).abs() < 200.0);
}

#[test]
fn a_blocked_rotor_is_reported_and_the_current_switched_off() {
    let params = ServoParams {
        // Friction beyond what 30 % current can turn.
        coulomb_friction_nm: 0.5,
        ..ServoParams::default()
    };
    let mut r = Rig::new(params, 0);
    r.enable_open_loop();
    let err = r.measure().unwrap_err();
    assert!(
        matches!(err, CommutationError::NotFollowing { moved: 0, .. }),
        "{err}"
    );
    assert_eq!(r.read(objects::COMMUTATION_CURRENT), [0, 0]);
}

/// The measurement as the master's cycle thread runs it
/// (`gantry_drives::commutation::CommutationProcedure`), emulated here as the engine does:
/// each cycle the drive's inputs (statusword, 0x6064) and the outcome of the one SDO access
/// on its way; the outputs it asks for stepped towards Operation enabled (as the channel
/// does for a lent drive: from Switch on disabled, the axis Disabled); its accesses served
/// by the drive's dictionary, answered the next cycle. `cancel_at`: a Stop at that cycle.
fn run_procedure(
    r: &mut Rig,
    cancel_at: Option<usize>,
) -> Result<(), gantry_drives::cia402::procedure::ProcedureFailure> {
    use gantry_drives::cia402::procedure::{ProcedureInputs, SdoOutcome};
    use gantry_drives::cia402::Statusword;
    use gantry_drives::commutation::CommutationProcedure;
    let pole_pairs = u32::from(r.read(objects::MOTOR_POLE_PAIRS)[0]);
    let config = CommutationConfig::new(r.d.params.counts_per_rev, pole_pairs);
    let mut p = CommutationProcedure::new(CommutationMeasurement::new(config).unwrap());
    let mut sdo: Option<SdoOutcome> = None;
    for n in 0..20_000 {
        if cancel_at == Some(n) {
            p.cancel("Stop");
        }
        // The cycle: the controlword towards Operation enabled (no PDO mode: 0x6060 goes
        // by SDO), then the drive's inputs.
        r.cw = match r.d.state() {
            State::SwitchOnDisabled => 0x06,
            State::ReadyToSwitchOn => 0x07,
            _ => 0x0F,
        };
        let position = r.cycle();
        let mut inp = [0u8; 6];
        r.d.publish_input_image(&mut inp);
        let sw = Statusword(u16::from_le_bytes([inp[0], inp[1]]));
        let io = ProcedureInputs {
            statusword: sw,
            mode_display: None,
            mode_mapped: false,
            now_s: r.t,
            position,
            sdo: sdo.take(),
        };
        let step = p.step(&io);
        if let Some(a) = step.sdo {
            sdo = Some(match a.write {
                Some(v) => {
                    let bytes = v.to_le_bytes();
                    match r
                        .od
                        .write(a.object.index, a.object.sub, &bytes[..a.object.kind.size()])
                    {
                        Ok(()) => {
                            r.d.take_objects(&r.od);
                            SdoOutcome::Done(0)
                        }
                        Err(_) => SdoOutcome::Aborted(0x0609_0030),
                    }
                }
                None => {
                    let b = r.read(a.object);
                    let mut raw = [0u8; 8];
                    raw[..b.len()].copy_from_slice(&b);
                    let v = i64::from_le_bytes(raw);
                    let shift = 64 - 8 * b.len() as u32;
                    SdoOutcome::Done((v << shift) >> shift)
                }
            });
        }
        if let Some(end) = step.end {
            return end;
        }
    }
    panic!("the procedure did not end");
}

#[test]
fn the_cycle_thread_procedure_measures_from_a_disabled_drive_and_ends_with_the_current_off() {
    let params = ServoParams {
        pole_pairs: 4,
        commutation_offset: 23_456,
        ..ServoParams::default()
    };
    let mut r = Rig::new(params, 5000);
    assert_eq!(r.d.state(), State::SwitchOnDisabled);
    run_procedure(&mut r, None).unwrap();
    let miss = electrical_error_deg(
        i64::from(r.d.commutation_setting),
        23_456,
        params.counts_per_rev,
        4,
    );
    assert!(miss.abs() <= 1.0, "{}: {miss}°", r.d.commutation_setting);
    assert_eq!(r.read(objects::COMMUTATION_CURRENT), [0, 0], "current off");
    assert_eq!(
        r.read(objects::MODES_OF_OPERATION_DISPLAY),
        [0xFF],
        "still open loop"
    );
    assert_eq!(r.d.error_code(), 0);

    // Cancelled while the vector turns: the current is switched off, the end says why.
    let mut r = Rig::new(params, 0);
    let e = run_procedure(&mut r, Some(1500)).unwrap_err();
    assert_eq!(
        e,
        gantry_drives::cia402::procedure::ProcedureFailure::Cancelled { by: "Stop" }
    );
    assert_eq!(r.read(objects::COMMUTATION_CURRENT), [0, 0], "current off");
    assert_eq!(r.d.commutation_setting, 0, "nothing written");
}
