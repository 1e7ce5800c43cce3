//! The progress bar and cancellation: ctrl-c sets a flag that the renderers poll through
//! [`Progress::cancelled`], so a render stops cleanly and nothing is written.

use indicatif::{ProgressBar, ProgressStyle};
use speckle::estimators::Progress;
use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Set by the ctrl-c handler (or by the hidden test option `--cancel-after-paths`).
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Whether ctrl-c was pressed (or a test cancellation fired).
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::Relaxed)
}

/// Installs the handler of ctrl-c (and of SIGTERM and SIGHUP). In a `cooperative` command
/// (one whose work polls [`interrupted`]) the first signal asks the work to stop: it then
/// exits with code 130 within a second and writes nothing. Otherwise, and at the second
/// signal, the process exits at once with code 130, after rolling back any output commit in
/// progress and removing its temporaries (`speckle_output::abandon`).
pub fn install_interrupt_handler(cooperative: bool) {
    let result = ctrlc::set_handler(move || {
        if !cooperative || INTERRUPTED.swap(true, Ordering::SeqCst) {
            speckle_output::abandon();
            tell!("\nspeckle: interrupted; no output was written");
            std::process::exit(130);
        }
        tell!("\nspeckle: interrupted, stopping the render (press ctrl-c again to exit at once)");
    });
    if let Err(e) = result {
        tell!("speckle: warning: cannot install the ctrl-c handler ({e})");
    }
}

/// A render's progress: an `indicatif` bar on stderr (hidden when stderr is not a terminal or
/// with `--quiet`) and the interrupt flag.
#[derive(Debug)]
pub struct CliProgress {
    bar: ProgressBar,
    done: AtomicU64,
    cancel_after: Option<u64>,
}

impl CliProgress {
    /// A bar for `total` units of work (`unit`: "paths", "configurations"), labelled `what`.
    /// `cancel_after` counts the same units.
    pub fn new(total: u64, unit: &str, what: &str, quiet: bool, cancel_after: Option<u64>) -> Self {
        let bar = if quiet || !std::io::stderr().is_terminal() {
            ProgressBar::hidden()
        } else {
            let bar = ProgressBar::new(total);
            let style = ProgressStyle::with_template(&format!(
                "{{msg}} [{{elapsed_precise}}] {{wide_bar}} {{human_pos}}/{{human_len}} {unit}, \
                 eta {{eta}}"
            ))
            .unwrap_or_else(|_| ProgressStyle::default_bar());
            bar.set_style(style);
            bar.set_message(what.to_string());
            bar
        };
        Self {
            bar,
            done: AtomicU64::new(0),
            cancel_after,
        }
    }

    /// Removes the bar from the terminal.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

impl Progress for CliProgress {
    fn advance(&self, units: u64) {
        self.bar.inc(units);
        let done = self.done.fetch_add(units, Ordering::Relaxed) + units;
        if self.cancel_after.is_some_and(|n| done >= n) {
            INTERRUPTED.store(true, Ordering::SeqCst);
        }
    }

    fn cancelled(&self) -> bool {
        interrupted()
    }
}
