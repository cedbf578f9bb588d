//! The cycle thread takes no lock: run under a seccomp filter that kills the process on
//! any `futex` call — what every lock, condition variable or parker does to wait or to
//! wake a waiter — the engine serves 3000 cycles at 1 kHz while the application hammers
//! it and the bus loses frames and a cable is pulled and plugged back. Two controls show
//! the filter catches a contended `Mutex` and a parking executor (`futures_lite::block_on`,
//! what the cycle used before the doorbell). The runs are child processes
//! (`cycle-under-seccomp`), since the filter ends the process it catches.

use std::os::unix::process::ExitStatusExt;
use std::process::{Command, Output};

fn probe(mode: &str) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cycle-under-seccomp"))
        .arg(mode)
        .output()
        .expect("the probe runs")
}

fn text(out: &Output) -> String {
    format!(
        "status {:?}\n{}{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// The number after `key ` in the probe's report.
fn figure(report: &str, key: &str) -> u64 {
    let at = report.find(&format!("{key} ")).expect(key) + key.len() + 1;
    report[at..]
        .split(|c: char| !c.is_ascii_digit())
        .next()
        .and_then(|n| n.parse().ok())
        .expect(key)
}

#[test]
fn the_cycle_thread_never_enters_a_futex() {
    let out = probe("engine");
    assert_eq!(
        out.status.signal(),
        None,
        "the cycle thread called futex (waited on or woke a lock): {}",
        text(&out)
    );
    assert!(out.status.success(), "{}", text(&out));
    let report = String::from_utf8_lossy(&out.stdout).into_owned();
    eprintln!("{report}");
    assert_eq!(figure(&report, "cycles"), 3000);
    assert!(
        figure(&report, "done") >= 8,
        "moves ran to the end: {report}"
    );
    assert!(figure(&report, "resets") >= 4, "{report}");
    assert!(figure(&report, "lost frames") >= 2, "{report}");
}

#[test]
fn a_contended_lock_in_the_filtered_thread_is_caught() {
    let out = probe("contended-lock");
    assert_eq!(out.status.signal(), Some(libc::SIGSYS), "{}", text(&out));
}

#[test]
fn a_parking_executor_in_the_filtered_thread_is_caught() {
    let out = probe("parking");
    assert_eq!(out.status.signal(), Some(libc::SIGSYS), "{}", text(&out));
}
