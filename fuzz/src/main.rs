//! AFL++ target of every reader of outside data: `readers <reader>` reads each input that AFL
//! gives it through `fuzz::readers::Target` (the same entry points as the test suite's mutation
//! pass). A crash is a panic that escapes the reader, an error that does not name the file, or an
//! allocation above 512 MiB (the global allocator aborts); a hang is AFL's time-out (`-t`).
//! Panics that a reader catches itself and reports as an error naming the file (third-party
//! parsers run under a guard) are not crashes (`fuzz_nohook`), as in the mutation pass.
//!
//! Without AFL (a plain `cargo build`), the binary reads one input from standard input, which
//! replays a crash: `target/release/readers ply < crash-file`.

use fuzz::readers::{Reader, Target};

#[global_allocator]
static ALLOC: fuzz::alloc::LimitAlloc = fuzz::alloc::LimitAlloc::new(512 << 20);

fn main() {
    let names: Vec<&str> = Reader::ALL.iter().map(|r| r.name()).collect();
    let Some(reader) = std::env::args().nth(1).and_then(|n| Reader::from_name(&n)) else {
        eprintln!("usage: readers <reader>, one of: {}", names.join(", "));
        std::process::exit(2);
    };
    let scratch = std::env::temp_dir().join(format!(
        "translucent-afl-{}-{}",
        reader.name(),
        std::process::id()
    ));
    let target = Target::new(reader, &scratch).unwrap_or_else(|e| panic!("{e}"));
    afl::fuzz_nohook!(|data: &[u8]| {
        if let Err(msg) = target.read(data) {
            assert!(
                target.names_input(&msg),
                "the error does not name the file: {msg}"
            );
        }
    });
}
