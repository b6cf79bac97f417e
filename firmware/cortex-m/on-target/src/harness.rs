//! A minimal test harness: each test prints `test NAME ... ok` or `... FAILED` over
//! semihosting; the run ends with `N passed, M failed` and exits with status 0 or 1.

use cortex_m_semihosting::{debug, hprint, hprintln};

/// What a test uses to report failed checks.
pub struct Ctx {
    name: &'static str,
    failures: u32,
}

impl Ctx {
    /// Records a failed check (printed at once, with where it happened).
    pub fn fail(&mut self, file: &str, line: u32, msg: core::fmt::Arguments<'_>) {
        if self.failures == 0 {
            hprintln!();
        }
        self.failures += 1;
        hprintln!("    [{}] {}:{}: {}", self.name, file, line, msg);
    }

    /// Number of failed checks so far.
    pub fn failures(&self) -> u32 {
        self.failures
    }
}

/// `check!(ctx, condition, "format", args...)`: records a failure when the condition is
/// false (the test goes on, so every failing check is reported).
#[macro_export]
macro_rules! check {
    ($ctx:expr, $cond:expr, $($fmt:tt)+) => {
        if !($cond) {
            $ctx.fail(file!(), line!(), format_args!($($fmt)+));
        }
    };
    ($ctx:expr, $cond:expr) => {
        if !($cond) {
            $ctx.fail(file!(), line!(), format_args!("{}", stringify!($cond)));
        }
    };
}

/// Runs tests and counts the results.
#[derive(Default)]
pub struct Runner {
    passed: u32,
    failed: u32,
    known: u32,
}

impl Runner {
    /// A runner with no results yet.
    pub const fn new() -> Self {
        Runner {
            passed: 0,
            failed: 0,
            known: 0,
        }
    }

    /// Runs one test.
    pub fn run(&mut self, name: &'static str, test: fn(&mut Ctx)) {
        hprint!("test {} ... ", name);
        let mut ctx = Ctx { name, failures: 0 };
        test(&mut ctx);
        if ctx.failures == 0 {
            self.passed += 1;
            hprintln!("ok");
        } else {
            self.failed += 1;
            hprintln!("test {} ... FAILED ({} failed checks)", name, ctx.failures);
        }
    }

    /// Runs a test of a known, reported bug in a crate this suite may not change: a
    /// failure is printed (`FAILED (known issue ...)`) but not counted, so the suite stays
    /// green until the fix lands; once it passes it counts as passed (then move it to
    /// [`Runner::run`]).
    pub fn known_issue(&mut self, name: &'static str, issue: &'static str, test: fn(&mut Ctx)) {
        let mut ctx = Ctx { name, failures: 0 };
        hprint!("test {} ... ", name);
        test(&mut ctx);
        if ctx.failures == 0 {
            self.passed += 1;
            hprintln!("ok (known issue no longer reproduces: {})", issue);
        } else {
            self.known += 1;
            hprintln!(
                "test {} ... FAILED (known issue, not counted: {})",
                name,
                issue
            );
        }
    }

    /// Prints `N passed, M failed` and ends the emulation, exit status 1 on any failure.
    pub fn finish(&self) -> ! {
        hprintln!();
        if self.known > 0 {
            hprintln!(
                "{} known issue(s) reproduced, not counted (see README.md)",
                self.known
            );
        }
        hprintln!("{} passed, {} failed", self.passed, self.failed);
        let status = if self.failed == 0 {
            debug::EXIT_SUCCESS
        } else {
            debug::EXIT_FAILURE
        };
        debug::exit(status);
        #[allow(clippy::empty_loop)]
        loop {}
    }
}
