//! Printing to standard output and standard error without panicking. `println!` panics when a
//! write fails (`> /dev/full`: "No space left on device"), which would end a command before
//! it writes its results. Here the first failed write to standard output is kept, later
//! output is dropped, the command goes on (a sweep finishes and writes its results), and
//! [`finish`] reports it at the end: `main` exits 1 with one line naming it. A closed pipe
//! (`shadowbench list | head`) is not an error: output just stops, as with other command-line
//! tools. A failed write to standard error is dropped: there is nowhere left to say it.

use std::fmt;
use std::io::Write;
use std::sync::Mutex;

/// The first failed write to standard output, if any.
static FAILED: Mutex<Option<std::io::Error>> = Mutex::new(None);

fn failed() -> bool {
    FAILED.lock().map_or(true, |f| f.is_some())
}

fn keep(e: std::io::Error) {
    if let Ok(mut f) = FAILED.lock() {
        f.get_or_insert(e);
    }
}

/// Writes `args` to standard output (see the module docs); use [`crate::out!`] and
/// [`crate::outln!`].
pub fn print(args: fmt::Arguments) {
    if failed() {
        return;
    }
    if let Err(e) = std::io::stdout().lock().write_fmt(args) {
        keep(e);
    }
}

/// Writes `args` to standard error, dropping a failure; use [`crate::errln!`].
pub fn eprint(args: fmt::Arguments) {
    let _ = std::io::stderr().lock().write_fmt(args);
}

/// Flushes standard output; the first write that failed, unless it was a closed pipe.
pub fn finish() -> Result<(), std::io::Error> {
    if let Err(e) = std::io::stdout().lock().flush() {
        keep(e);
    }
    match FAILED.lock().ok().and_then(|mut f| f.take()) {
        Some(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e),
        _ => Ok(()),
    }
}

/// `print!` that never panics ([`print`]).
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::util::console::print(format_args!($($arg)*))
    };
}

/// `println!` that never panics ([`print`]).
#[macro_export]
macro_rules! outln {
    () => {
        $crate::util::console::print(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::util::console::print(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `eprintln!` that never panics ([`eprint`]).
#[macro_export]
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::util::console::eprint(format_args!("{}\n", format_args!($($arg)*)))
    };
}
