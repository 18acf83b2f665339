//! The kernel settings read this process's environment: checked in a child process (this test
//! binary again, running one test) whose environment the test sets, so that what the functions
//! read is known, not the environment `cargo test` happens to pass on.
use std::process::Command;

use ipdf_model::{REPRODUCIBLE_CPU_KERNELS, kernel_settings, missing_kernel_settings};

/// Set in the child's environment: the child prints what the functions return.
const CHILD: &str = "IPDF_KERNELS_CHILD";

#[test]
#[ignore = "the child process of the_settings_missing_are_those_the_environment_lacks"]
fn print_the_kernel_settings() {
    if std::env::var_os(CHILD).is_some() {
        println!("missing {:?}", missing_kernel_settings());
        println!("settings {:?}", kernel_settings());
    }
}

#[test]
fn the_settings_missing_are_those_the_environment_lacks() {
    let mut child = Command::new(std::env::current_exe().unwrap());
    child.args([
        "kernels::print_the_kernel_settings",
        "--exact",
        "--ignored",
        "--nocapture",
        "--test-threads",
        "1",
    ]);
    for (name, _) in REPRODUCIBLE_CPU_KERNELS {
        child.env_remove(name);
    }
    // A user who chose the wider kernels for ATen: that one is not missing, the other two are.
    let out = child
        .env(CHILD, "1")
        .env("ATEN_CPU_CAPABILITY", "avx512")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    assert!(
        stdout.contains(r#"missing [("ONEDNN_MAX_CPU_ISA", "AVX2"), ("MKL_CBWR", "AVX2,STRICT")]"#),
        "{stdout}"
    );
    assert!(
        stdout.contains(
            r#"settings [("ATEN_CPU_CAPABILITY", Some("avx512")), ("ONEDNN_MAX_CPU_ISA", None), ("MKL_CBWR", None)]"#
        ),
        "{stdout}"
    );
}
