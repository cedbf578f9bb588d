//! A seccomp filter that kills the process when the calling thread enters a futex. Every
//! lock or condition variable that has to wait (std's `Mutex`, `Condvar`, a parker, glibc's
//! malloc locks) or wake a waiter goes through `futex`; a thread that never calls it never
//! blocks on, nor hands off, a lock. The tests install it in the cycle thread to prove the
//! rule "no locks in the RT path" rather than take it on trust.

use std::io;

/// `struct seccomp_data` offsets (linux/seccomp.h).
const SECCOMP_DATA_NR: u32 = 0;
const SECCOMP_DATA_ARCH: u32 = 4;

/// Classic BPF opcodes (linux/bpf_common.h): class | size | mode.
const BPF_LD: u16 = 0x00;
const BPF_JMP: u16 = 0x05;
const BPF_RET: u16 = 0x06;
const BPF_W: u16 = 0x00;
const BPF_ABS: u16 = 0x20;
const BPF_JEQ: u16 = 0x10;
const BPF_K: u16 = 0x00;
const BPF_LD_W_ABS: u16 = BPF_LD | BPF_W | BPF_ABS;
const BPF_JMP_JEQ_K: u16 = BPF_JMP | BPF_JEQ | BPF_K;
const BPF_RET_K: u16 = BPF_RET | BPF_K;

/// Filter results and the `seccomp(2)` operation (linux/seccomp.h).
const SECCOMP_RET_ALLOW: u32 = 0x7fff_0000;
const SECCOMP_RET_KILL_PROCESS: u32 = 0x8000_0000;
const SECCOMP_SET_MODE_FILTER: libc::c_ulong = 1;

/// The architecture the system call numbers below belong to (linux/audit.h).
#[cfg(target_arch = "x86_64")]
const AUDIT_ARCH_NATIVE: u32 = 0xC000_003E;
#[cfg(target_arch = "aarch64")]
const AUDIT_ARCH_NATIVE: u32 = 0xC000_00B7;

/// `futex_waitv(2)`, the same number on every architecture that has it.
const SYS_FUTEX_WAITV: libc::c_long = 449;

fn op(code: u16, jt: u8, jf: u8, k: u32) -> libc::sock_filter {
    libc::sock_filter { code, jt, jf, k }
}

/// From now on, the calling thread (and threads it starts) may not call `futex` or
/// `futex_waitv`: the kernel kills the process with SIGSYS if it does. Other threads are
/// not affected. Cannot be undone.
pub fn forbid_futex_in_this_thread() -> io::Result<()> {
    let mut filter = [
        op(BPF_LD_W_ABS, 0, 0, SECCOMP_DATA_ARCH),
        // A system call of a foreign ABI (e.g. i386 on x86-64): kill.
        op(BPF_JMP_JEQ_K, 0, 4, AUDIT_ARCH_NATIVE),
        op(BPF_LD_W_ABS, 0, 0, SECCOMP_DATA_NR),
        op(BPF_JMP_JEQ_K, 2, 0, libc::SYS_futex as u32),
        op(BPF_JMP_JEQ_K, 1, 0, SYS_FUTEX_WAITV as u32),
        op(BPF_RET_K, 0, 0, SECCOMP_RET_ALLOW),
        op(BPF_RET_K, 0, 0, SECCOMP_RET_KILL_PROCESS),
    ];
    let program = libc::sock_fprog {
        len: filter.len() as u16,
        filter: filter.as_mut_ptr(),
    };
    // SAFETY: prctl with integer arguments.
    if unsafe { libc::prctl(libc::PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) } != 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: `program` points at `filter`, both alive for the call; flags 0 = this thread
    // only (no TSYNC).
    let r = unsafe {
        libc::syscall(
            libc::SYS_seccomp,
            SECCOMP_SET_MODE_FILTER,
            0 as libc::c_ulong,
            &program as *const libc::sock_fprog,
        )
    };
    if r != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}
