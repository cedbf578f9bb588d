//! Homing runs interrupted by anything a user can send (Stop, Halt, moves, Reset, power,
//! quick stop, SetReference, another homing run), at random cycles, against the axis
//! model: the state machine never takes a transition PLCopen does not have (debug builds
//! stop on one), the set speed never exceeds the axis maximum, and the axis becomes homed
//! only through a homing run that ends Done or a SetReference.

mod homing_model;

use gantry_kernel::axis::command::{
    Command, HaltMode, MoveDirection, MovePtp, MoveVelocity, PositioningMode, PowerCommand,
};
use gantry_kernel::axis::handle::{CommandStatus, HandleId};
use gantry_kernel::homing::{
    HomeDirection, HomingMode, MoveHome, MoveHomeCall, StepAbsoluteSwitch, SwitchConfig, SwitchMode,
};
use homing_model::*;

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

fn command(r: &mut Rng) -> Command {
    let dir = if r.below(2) == 0 {
        MoveDirection::Positive
    } else {
        MoveDirection::Negative
    };
    let modes = [
        HomingMode::ZeroPulse1Phase,
        HomingMode::ZeroPulse2Phase,
        HomingMode::SwitchingEdge1Phase,
        HomingMode::SwitchingEdge2Phase,
    ];
    let configs = [
        SwitchConfig::NoSwitch,
        SwitchConfig::RefAndLimitSwitch,
        SwitchConfig::RefSwitch,
        SwitchConfig::LimitSwitch,
    ];
    match r.below(14) {
        0..=2 => Command::MoveHome(MoveHomeCall::all(MoveHome {
            direction: dir,
            switch_config: configs[r.below(4) as usize],
            mode: modes[r.below(4) as usize],
            acceleration: 300.0,
            jerk: 10_000.0,
            speed_switch_search: 30.0,
            max_distance_switch_search: 500.0,
            speed_reference_search: 5.0,
            max_distance_reference_search: 100.0,
            reference_offset: -2.0 * dir.sign(),
            normal_position: 0.0,
        })),
        3..=4 => Command::StepAbsoluteSwitch(StepAbsoluteSwitch {
            direction: HomeDirection::ALL[r.below(4) as usize],
            switch_mode: SwitchMode::ALL[r.below(8) as usize],
            position: 0.0,
            velocity: 20.0,
            acceleration: 200.0,
            deceleration: 200.0,
            jerk: 5_000.0,
            distance_limit: 1_000.0,
        }),
        5 => Command::Stop { deceleration: None },
        6 => Command::Release,
        7 => Command::Halt {
            mode: HaltMode::Normal,
            deceleration: None,
        },
        8 => Command::MovePtp(MovePtp::new(
            PositioningMode::RelActual,
            (r.below(41) as f64 - 20.0) * 2.0,
        )),
        9 => Command::MoveVelocity(MoveVelocity::new(dir, 10.0)),
        10 => Command::Reset,
        11 => Command::Power(PowerCommand::Enable),
        12 => Command::QuickStop,
        _ => Command::SetReference(0.0),
    }
}

#[test]
fn homing_interrupted_at_random_keeps_the_state_machine_and_homed_flag_honest() {
    let mut commands = 0;
    let mut runs_done = 0;
    let mut runs_interrupted = 0;
    for seed in 1..=16u64 {
        let mut homing_done = 0;
        let mut r = Rng(0xD1B5_4A32_D192_ED03 ^ seed.wrapping_mul(0x9E37_79B9));
        let x0 = r.below(180) as f64 - 90.0;
        let mut rig = Rig::new(axis_config(), Layout::STANDARD, x0);
        let mut homing: Vec<HandleId> = Vec::new();
        let mut homed = false;
        for cycle in 0..60_000 {
            let mut set_reference = false;
            if r.below(400) == 0 {
                let cmd = command(&mut r);
                if let Ok(h) = rig.k.command(0, cmd) {
                    commands += 1;
                    match cmd {
                        Command::MoveHome(_) | Command::StepAbsoluteSwitch(_) => homing.push(h),
                        Command::SetReference(_) => set_reference = true,
                        _ => {}
                    }
                }
            }
            let s = rig.cycle();
            let done_now = homing
                .iter()
                .filter(|h| rig.k.command_status(**h) == CommandStatus::Done)
                .count();
            let now_homed = s.status.bits.homed;
            if now_homed && !homed {
                assert!(
                    set_reference || done_now > homing_done,
                    "seed {seed} cycle {cycle}: homed without a run or SetReference"
                );
            }
            homing_done = homing_done.max(done_now);
            homed = now_homed;
            assert!(
                s.status.set.v.abs() <= 100.0 * (1.0 + 1e-9),
                "seed {seed} cycle {cycle}: {}",
                s.status.set.v
            );
            assert_eq!(rig.k.axes()[0].refused_transitions(), 0);
        }
        for h in &homing {
            match rig.k.command_status(*h) {
                CommandStatus::Done => runs_done += 1,
                CommandStatus::Aborted | CommandStatus::Error(_) => runs_interrupted += 1,
                _ => {}
            }
        }
    }
    eprintln!("{commands} commands, {runs_done} runs done, {runs_interrupted} interrupted");
    // Not vacuous: many commands, runs that finished and runs that were interrupted.
    assert!(commands > 700, "{commands} commands taken");
    assert!(
        runs_done >= 5 && runs_interrupted >= 20,
        "{runs_done} runs done, {runs_interrupted} interrupted"
    );
}
