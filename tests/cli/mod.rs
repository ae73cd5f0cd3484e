//! The `afe` command line contract: outputs, and one clear error line (non-zero exit, no
//! output file) for every kind of bad input.
//!
//! One module per part of the contract: what `afe extract` writes, its bad inputs, its
//! outputs' paths, `afe list`, and threads, traces and `afe bench`.

mod bad_input;
mod extract;
mod list;
mod outputs;
mod threads;

/// Runs `afe args` with its standard output closed (a reader that went away); returns
/// what it wrote to standard error.
fn with_stdout_closed(args: &[&str]) -> String {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_afe"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run");
    drop(child.stdout.take());
    let res = child.wait_with_output().expect("wait");
    String::from_utf8_lossy(&res.stderr).into_owned()
}
