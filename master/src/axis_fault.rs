//! An axis fault as a user reads it: a drive's error code with its meaning (the kernel
//! knows the code, the drive layer its text; the master puts them together).

use gantry_drives::cia402::error_code::describe;
use gantry_kernel::axis::status::AxisFault;

/// `fault` in words: drive faults with their code and meaning, others as the kernel says.
pub fn describe_fault(fault: &AxisFault) -> String {
    match fault {
        AxisFault::Drive { code } => format!("drive fault 0x{code:04X}: {}", describe(*code)),
        AxisFault::Encoder { code } => format!(
            "encoder input failed 0x{code:04X}: {}",
            crate::runtime::encoder_input::describe(*code)
        ),
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drive_fault_reads_with_its_code_and_meaning() {
        assert_eq!(
            describe_fault(&AxisFault::Drive { code: 0x8700 }),
            "drive fault 0x8700: sync controller error (process data watchdog: the master stopped sending)"
        );
    }
}
