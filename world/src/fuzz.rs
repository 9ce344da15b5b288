//! Fuzzing helpers for the file readers' tests.
//!
//! - [`mutations`]: a cheap deterministic fuzz run by every `cargo test`: a valid file with
//!   a few bytes replaced, many times over, from a fixed xorshift stream (the same cases on
//!   every run).
//! - [`write_seeds`]: the seed corpora of the coverage-guided fuzz targets in `fuzz/`
//!   (cargo-fuzz, libFuzzer), written by the tests that check the seeds are valid inputs,
//!   from the tests' own encoders: generated at run time, never committed.

/// The environment variable naming the folder [`write_seeds`] writes into.
pub const SEEDS_ENV: &str = "SADESIM_FUZZ_SEEDS";

/// `cases` copies of `good`, each with 3 bytes replaced at positions `pick(random)` chooses
/// (given a random `u64`; reduce it modulo the file's length for uniform positions).
pub fn mutations(good: &[u8], cases: usize, seed: u64, pick: impl Fn(u64) -> usize) -> Vec<Vec<u8>> {
    let mut state = seed | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    (0..cases)
        .map(|_| {
            let mut bytes = good.to_vec();
            for _ in 0..3 {
                let r = next();
                let i = pick(r) % bytes.len();
                bytes[i] = (r >> 40) as u8;
            }
            bytes
        })
        .collect()
}

/// Writes `seeds` (`(file name, bytes)`) into `$SADESIM_FUZZ_SEEDS/<target>/` when that
/// variable is set (`tests/fuzz.sh` sets it); does nothing otherwise.
///
/// # Panics
/// When the folder or a file cannot be written (a test helper: the test fails).
pub fn write_seeds(target: &str, seeds: &[(&str, Vec<u8>)]) {
    let Some(root) = std::env::var_os(SEEDS_ENV) else { return };
    let dir = std::path::Path::new(&root).join(target);
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    for (name, bytes) in seeds {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }
}
