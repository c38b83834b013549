//! Clean interruption of the long commands (`track`, `demo`; issue #32).
//!
//! [`install`] turns the first SIGINT (Ctrl-C) or SIGTERM into a flag that the command polls
//! between frames ([`requested`]): it finishes the frame in hand, closes its outputs (the
//! MCAP with its summary and footer, stdout on a complete line), and returns [`Interrupted`],
//! which `main` reports in one line with exit code 130 (SIGINT) or 143 (SIGTERM), the shell's
//! `128 + signal`. A second signal while it finishes ends the process at once with that code.
//! Commands that do not call [`install`] keep the default action (the process ends).
//!
//! A command blocked reading its input (a y4m stream on a quiet pipe) sees the flag when the
//! next frame or the end of the input arrives; a producer started from the same shell
//! (`ffmpeg ... | formation-tracker track -`) gets the same Ctrl-C and closes the pipe.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use signal_hook::consts::{SIGINT, SIGTERM};

/// The signal received, 0 for none.
static SIGNAL: AtomicUsize = AtomicUsize::new(0);
/// Set by the first signal: the next one exits at once.
static ARMED: AtomicBool = AtomicBool::new(false);

/// Registers the handlers (once per process; later calls do nothing).
///
/// # Errors
/// The operating system refused to install a handler.
pub fn install() -> Result<(), super::CliError> {
    static INSTALLED: AtomicBool = AtomicBool::new(false);
    if INSTALLED.swap(true, Ordering::SeqCst) {
        return Ok(());
    }
    for signal in [SIGINT, SIGTERM] {
        let fail = |e: std::io::Error| format!("cannot handle signal {signal}: {e}");
        // Order matters: the exit is checked before this signal arms it.
        signal_hook::flag::register_conditional_shutdown(signal, 128 + signal, &ARMED)
            .map_err(fail)?;
        signal_hook::flag::register_usize(signal, &SIGNAL, signal as usize).map_err(fail)?;
        signal_hook::flag::register(signal, &ARMED).map_err(fail)?;
    }
    Ok(())
}

/// The signal that asked the command to stop, if one did.
pub fn requested() -> Option<i32> {
    match SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        s => i32::try_from(s).ok(),
    }
}

/// `Err(`[`Interrupted`]`)` when a signal asked the command to stop; `done` says what was
/// done and kept.
///
/// # Errors
/// [`Interrupted`], if a signal came.
pub fn stopped(done: impl FnOnce() -> String) -> Result<(), super::CliError> {
    match requested() {
        Some(signal) => Err(Interrupted {
            signal,
            done: done(),
        }
        .into()),
        None => Ok(()),
    }
}

/// The command stopped early on a signal, after finishing its frame and closing its outputs.
#[derive(Debug, thiserror::Error)]
#[error("interrupted by {name}: {done}", name = signal_name(*.signal))]
pub struct Interrupted {
    /// The signal number (2 SIGINT, 15 SIGTERM).
    pub signal: i32,
    /// What was done and kept, for the message.
    pub done: String,
}

impl Interrupted {
    /// The exit code: `128 + signal` (130 for SIGINT, 143 for SIGTERM).
    pub fn exit_code(&self) -> u8 {
        u8::try_from(128 + self.signal).unwrap_or(130)
    }
}

fn signal_name(signal: i32) -> &'static str {
    match signal {
        SIGINT => "SIGINT",
        SIGTERM => "SIGTERM",
        _ => "a signal",
    }
}
