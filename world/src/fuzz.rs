//! A cheap deterministic fuzz for the file readers' tests: a valid file with a few bytes
//! replaced, many times over, from a fixed xorshift stream (the same cases on every run).

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
