//! SIGINT and SIGTERM during `bettimill build`, handled from the first instruction of
//! `main` on (before arguments are parsed, the manifest is read or the plan is made).
//!
//! Two modes:
//! - While no worker runs (start-up: planning, creating or checking the directory; and
//!   after the workers have stopped: finalize), a signal ends the process at once with
//!   exit code 130 and a one-line message on stderr. Nothing needs undoing: every file is
//!   written under a temporary name and renamed, the temporaries are removed by the next
//!   build, and a creation stopped half-way is finished by it.
//! - While workers run ([`Watching`] is alive, inside the coordinator's control future), a
//!   signal only sets a flag: the coordinator stops its workers, removes their temporaries
//!   and the build returns 130 with its `resume with:` line.
//!
//! The handlers are registered in `main`'s own thread before anything else runs; the signals
//! are received on a thread of their own (the handler itself only writes to a pipe that
//! wakes that thread), so what follows a signal is ordinary code.

use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::OnceLock;

const EXIT: u8 = 0;
const FLAG: u8 = 1;

static MODE: AtomicU8 = AtomicU8::new(EXIT);
static INTERRUPTED: AtomicBool = AtomicBool::new(false);
static MESSAGE: OnceLock<String> = OnceLock::new();

/// The message before the command line is known (the resume command is set once the
/// arguments are parsed).
const DEFAULT_MESSAGE: &str =
    "interrupted while no worker was running; nothing partial is visible; resume with: the same command";

/// Installs the handling of SIGINT and SIGTERM and returns once the handlers are in place;
/// later calls do nothing. Called first thing in `main` (and in [`crate::run`], for the
/// Python console script), for `build` only.
pub fn install() {
    static INSTALLED: std::sync::Once = std::sync::Once::new();
    INSTALLED.call_once(install_once);
}

/// The handlers are registered on the calling thread before any other thread or runtime
/// exists (a signal that arrives before the receiving thread runs waits in the handler's
/// pipe), so the window in which a signal kills the process is the time before `main`.
#[cfg(unix)]
fn install_once() {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else {
        return;
    };
    let _ = std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            for _ in signals.forever() {
                received();
            }
        });
}

#[cfg(not(unix))]
fn install_once() {
    let (ready, installed) = std::sync::mpsc::channel();
    let spawned = std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            let Ok(runtime) = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
            else {
                let _ = ready.send(());
                return;
            };
            runtime.block_on(async move {
                let _ = ready.send(());
                while tokio::signal::ctrl_c().await.is_ok() {
                    received();
                }
            });
        });
    if spawned.is_ok() {
        let _ = installed.recv();
    }
}

fn received() {
    if MODE.load(Ordering::SeqCst) == FLAG {
        INTERRUPTED.store(true, Ordering::SeqCst);
        return;
    }
    crate::printer::Printer::always(MESSAGE.get().map_or(DEFAULT_MESSAGE, String::as_str));
    std::process::exit(130);
}

/// Sets the message printed when a signal ends the process outside the workers' run.
pub fn set_resume_command(resume: &str) {
    let _ = MESSAGE.set(format!(
        "interrupted while no worker was running; nothing partial is visible; resume with: {resume}"
    ));
}

/// Whether a signal arrived while a [`Watching`] was alive.
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// While alive, signals set the flag [`interrupted`] reads instead of ending the process.
pub struct Watching(());

impl Watching {
    /// Switches to flag mode.
    pub fn start() -> Watching {
        MODE.store(FLAG, Ordering::SeqCst);
        Watching(())
    }
}

impl Drop for Watching {
    fn drop(&mut self) {
        MODE.store(EXIT, Ordering::SeqCst);
    }
}
