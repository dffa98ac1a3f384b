//! An allocator that refuses oversized allocations: a fuzzing binary installs it as its
//! `#[global_allocator]` so that a count read from a file header (a 4-byte count asking for
//! 16 GiB) shows up as a failure of the input that caused it, not as a machine out of memory.
//!
//! A request above the limit is reported on standard error with the current input's context
//! ([`set_context`]: reader, case, the file it was read from), that file is copied to the path
//! the context names, and the request fails, which aborts the process (`handle_alloc_error`).
//! Everything else goes to the system allocator.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::{Cell, RefCell};
use std::io::Write;
use std::path::PathBuf;

/// The global allocator of a fuzzing binary: [`System`] below `limit` bytes per allocation.
pub struct LimitAlloc {
    limit: usize,
}

impl LimitAlloc {
    /// An allocator refusing single allocations above `limit` bytes.
    pub const fn new(limit: usize) -> Self {
        LimitAlloc { limit }
    }
}

/// What is being read on this thread, for the report of a refused allocation.
struct Context {
    what: String,
    input: PathBuf,
    keep_as: PathBuf,
}

thread_local! {
    static CONTEXT: RefCell<Option<Context>> = const { RefCell::new(None) };
    static REPORTING: Cell<bool> = const { Cell::new(false) };
}

/// Sets the context of this thread's next reads: `what` (reader and case), the input file, and
/// where to keep a copy of it should an allocation be refused.
pub fn set_context(what: String, input: PathBuf, keep_as: PathBuf) {
    CONTEXT.with(|c| {
        *c.borrow_mut() = Some(Context {
            what,
            input,
            keep_as,
        })
    });
}

/// Clears this thread's context.
pub fn clear_context() {
    CONTEXT.with(|c| *c.borrow_mut() = None);
}

/// Reports a refused allocation of `size` bytes (allocations made here go to the system).
fn report(size: usize, limit: usize) {
    if REPORTING.with(|r| r.replace(true)) {
        return;
    }
    let mut msg = format!(
        "\nfuzz: refused an allocation of {size} bytes (limit {limit}): an allocation driven by \
         the input"
    );
    let _ = CONTEXT.try_with(|c| {
        if let Ok(c) = c.try_borrow()
            && let Some(c) = c.as_ref()
        {
            if let Some(dir) = c.keep_as.parent() {
                let _ = std::fs::create_dir_all(dir);
            }
            let kept = std::fs::copy(&c.input, &c.keep_as).is_ok();
            msg.push_str(&format!(
                "\n  while reading: {}\n  input: {}{}",
                c.what,
                c.input.display(),
                if kept {
                    format!(" (copied to {})", c.keep_as.display())
                } else {
                    String::new()
                }
            ));
        }
    });
    msg.push('\n');
    // Straight to the file descriptor: the test harness's output capture would be lost in the
    // abort that follows.
    let _ = std::io::stderr().write_all(msg.as_bytes());
    REPORTING.with(|r| r.set(false));
}

// SAFETY: every method forwards to `System` with the caller's layout, or returns null (a failed
// allocation, which the caller must handle) without touching memory.
unsafe impl GlobalAlloc for LimitAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > self.limit {
            report(layout.size(), self.limit);
            return std::ptr::null_mut();
        }
        // SAFETY: forwarded with the caller's contract.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if layout.size() > self.limit {
            report(layout.size(), self.limit);
            return std::ptr::null_mut();
        }
        // SAFETY: forwarded with the caller's contract.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded with the caller's contract.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > self.limit {
            report(new_size, self.limit);
            return std::ptr::null_mut();
        }
        // SAFETY: forwarded with the caller's contract.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}
