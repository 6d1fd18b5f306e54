//! The stable half of fuzzing, run by every `cargo test`: each cargo-fuzz target's body
//! (`fuzz/bodies/<target>.rs`, the same file the `fuzz_target!` wraps) is run on
//!
//! 1. every file of `fuzz/corpus/<target>/` (missing or empty: the test fails, saying so);
//! 2. every file of `fuzz/artifacts/<target>/`, if there is any (crashes found earlier by
//!    `ci/fuzz.sh` stay fixed);
//! 3. `mutations` inputs made from the corpus by simple mutations (bit flips, interesting
//!    bytes, truncation, splicing two inputs, inserted garbage, deleted and repeated ranges),
//!    from a fixed seed, then as many again from `FUZZ_SEED` if it is set. `FUZZ_MUTATIONS`
//!    overrides the count (a longer local run: `FUZZ_MUTATIONS=1000000`).
//!
//! Not coverage-guided (that is `ci/fuzz.sh`, nightly + cargo-fuzz): a cheap check on stable
//! that the invariants still hold on the kept corpus and near it.
//!
//! A failure names the target and the input (corpus file, or seed and mutation number) and
//! writes the input to `target/fuzz-failures/<target>/<hash>`, which `cargo fuzz run <target>
//! <file>` replays. Each target prints one line (to stderr, past the test harness's capture):
//! how many inputs ran and how long they took.
//!
//! Shared by the three crates' `tests/fuzz_corpus.rs` through `#[path]`: those are the
//! crates that own the bodies, so this file is test support, not a crate of its own.

use std::fmt::Write as _;
use std::io::Write as _;
use std::panic::{self, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The seed every run uses; `FUZZ_SEED` adds a second one.
const FIXED_SEED: u64 = 0x5EED_C2F0;

/// Failing inputs reported in full before the test gives up (corpus and artifacts).
const MAX_REPORTED: usize = 8;

/// One fuzz target of the crate whose test includes this file.
pub struct Target {
    /// The cargo-fuzz target's name (its `[[bin]]`, its corpus folder).
    pub name: &'static str,
    /// The body: panics (a failed assert) on an input that breaks an invariant.
    pub body: fn(&[u8]),
    /// Mutated inputs per seed.
    pub mutations: usize,
}

/// Replays the target's corpus and artifacts, then its mutations; panics on the first
/// mutation that fails, or after the corpus and artifacts if any of those failed.
pub fn check(target: &Target) {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let name = target.name;
    let started = Instant::now();

    let corpus_dir = crate_dir.join("fuzz/corpus").join(name);
    let corpus = read_dir(&corpus_dir).unwrap_or_else(|e| {
        panic!(
            "fuzz target `{name}`: no corpus: {} ({e}); every target needs at least one seed \
             input there",
            corpus_dir.display()
        )
    });
    assert!(
        !corpus.is_empty(),
        "fuzz target `{name}`: the corpus folder {} is empty; every target needs at least one \
         seed input there",
        corpus_dir.display()
    );
    let artifacts_dir = crate_dir.join("fuzz/artifacts").join(name);
    let artifacts = if artifacts_dir.is_dir() {
        read_dir(&artifacts_dir)
            .unwrap_or_else(|e| panic!("fuzz target `{name}`: {}: {e}", artifacts_dir.display()))
    } else {
        Vec::new()
    };

    let (mut failed, mut failures) = (0, Vec::new());
    for (path, data) in corpus.iter().chain(&artifacts) {
        if let Err(message) = run(target.body, data) {
            failed += 1;
            if failures.len() < MAX_REPORTED {
                let saved = save(name, data);
                failures.push(format!(
                    "input {}: {message}\n  saved as {}",
                    path.display(),
                    saved.display()
                ));
            }
        }
    }
    if failed > 0 {
        panic!(
            "fuzz target `{name}`: {failed} input(s) of the corpus or artifacts break an \
             invariant (at most {MAX_REPORTED} shown){}\nreplay one: cd {} && cargo +nightly \
             fuzz run {name} <file>",
            failures.iter().fold(String::new(), |mut s, f| {
                let _ = write!(s, "\n- {f}");
                s
            }),
            crate_dir.display()
        );
    }

    let mutations = match std::env::var("FUZZ_MUTATIONS") {
        Ok(n) => n
            .parse()
            .unwrap_or_else(|_| panic!("FUZZ_MUTATIONS={n:?}: not a count")),
        Err(_) => target.mutations,
    };
    let mut seeds = vec![FIXED_SEED];
    if let Ok(text) = std::env::var("FUZZ_SEED") {
        seeds.push(parse_seed(&text));
    }
    let pool: Vec<&[u8]> = corpus
        .iter()
        .chain(&artifacts)
        .map(|(_, data)| data.as_slice())
        .collect();
    let max_len = pool.iter().map(|d| d.len()).max().unwrap_or(0).max(256) * 2;
    for &seed in &seeds {
        for index in 0..mutations {
            let input = mutate(&mut Rng::new(seed, name, index), &pool, max_len);
            if let Err(message) = run(target.body, &input) {
                let saved = save(name, &input);
                panic!(
                    "fuzz target `{name}`: mutation {index} of seed {seed:#x} breaks an \
                     invariant: {message}\n  saved as {}\nreplay: cd {} && cargo +nightly fuzz \
                     run {name} {}",
                    saved.display(),
                    crate_dir.display(),
                    saved.display()
                );
            }
        }
    }

    let line = format!(
        "fuzz-corpus: {name}: {} corpus + {} artifact + {} mutated inputs (seeds {}) in {:.2} s\n",
        corpus.len(),
        artifacts.len(),
        mutations * seeds.len(),
        seeds
            .iter()
            .map(|s| format!("{s:#x}"))
            .collect::<Vec<_>>()
            .join(", "),
        started.elapsed().as_secs_f64()
    );
    // Straight to stderr: the test harness captures `eprintln!` of passing tests.
    let _ = std::io::stderr().write_all(line.as_bytes());
}

/// The body on one input: `Err` with the panic's message if it panicked.
fn run(body: fn(&[u8]), data: &[u8]) -> Result<(), String> {
    panic::catch_unwind(AssertUnwindSafe(|| body(data))).map_err(|payload| {
        payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "panic with a non-text payload".to_string())
    })
}

/// Every regular file of `dir`, by name (deterministic order), with its bytes.
fn read_dir(dir: &Path) -> std::io::Result<Vec<(PathBuf, Vec<u8>)>> {
    let mut paths = Vec::new();
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        if entry.file_type()?.is_file() {
            paths.push(entry.path());
        }
    }
    paths.sort();
    paths
        .into_iter()
        .map(|path| std::fs::read(&path).map(|data| (path, data)))
        .collect()
}

/// Writes a failing input to `target/fuzz-failures/<target>/<hash>` and returns that path.
fn save(name: &str, data: &[u8]) -> PathBuf {
    // CARGO_TARGET_TMPDIR is `<target dir>/tmp` (set for integration tests).
    let target_dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .parent()
        .expect("the target dir holds tmp/")
        .to_path_buf();
    let dir = target_dir.join("fuzz-failures").join(name);
    let path = dir.join(format!("{:016x}", fnv1a(data)));
    if let Err(e) = std::fs::create_dir_all(&dir).and_then(|()| std::fs::write(&path, data)) {
        let _ = writeln!(
            std::io::stderr(),
            "fuzz-corpus: could not save {}: {e}",
            path.display()
        );
    }
    path
}

fn parse_seed(text: &str) -> u64 {
    let text = text.trim();
    let parsed = match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => u64::from_str_radix(hex, 16),
        None => text.parse(),
    };
    parsed.unwrap_or_else(|_| panic!("FUZZ_SEED={text:?}: not a decimal or 0x-hex u64"))
}

fn fnv1a(data: &[u8]) -> u64 {
    data.iter().fold(0xcbf2_9ce4_8422_2325, |hash, &b| {
        (hash ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// SplitMix64: small, fast, good enough to pick mutations. One generator per mutation
/// (from the seed, the target and the mutation's number), so a mutation does not depend on
/// the ones before it.
struct Rng(u64);

impl Rng {
    fn new(seed: u64, target: &str, index: usize) -> Self {
        let mut rng = Rng(seed ^ fnv1a(target.as_bytes()) ^ (index as u64).rotate_left(32));
        rng.next();
        rng
    }

    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform enough in `0..n`; 0 when `n` is 0.
    fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next() % n as u64) as usize
        }
    }

    /// A position in `0..=len` (an insertion point or a cut).
    fn cut(&mut self, len: usize) -> usize {
        self.below(len + 1)
    }
}

/// Bytes that parsers treat specially: bounds, line ends, TOML and number syntax.
const INTERESTING: &[u8] = b"\x00\x01\x7f\x80\xff\xfe\x0f\xfd\n\r\t \"'=[].,-+#019eEx_{}\\";

/// One input: a corpus entry with one to four mutations stacked, at most `max_len` bytes.
fn mutate(rng: &mut Rng, pool: &[&[u8]], max_len: usize) -> Vec<u8> {
    let mut data = pool[rng.below(pool.len())].to_vec();
    for _ in 0..1 + rng.below(4) {
        let len = data.len();
        match rng.below(9) {
            0 if len > 0 => {
                let at = rng.below(len);
                data[at] ^= 1 << rng.below(8);
            }
            1 if len > 0 => {
                let at = rng.below(len);
                data[at] = INTERESTING[rng.below(INTERESTING.len())];
            }
            2 if len > 0 => {
                let at = rng.below(len);
                data[at] = data[at].wrapping_add(rng.below(9) as u8).wrapping_sub(4);
            }
            3 => data.truncate(rng.cut(len)),
            4 => {
                // Splice: this input's head, another's tail.
                let other = pool[rng.below(pool.len())];
                data.truncate(rng.cut(len));
                data.extend_from_slice(&other[rng.cut(other.len())..]);
            }
            5 => {
                // Garbage: random bytes, or printable ones (text parsers reject most others).
                let at = rng.cut(len);
                let printable = rng.below(2) == 0;
                let garbage: Vec<u8> = (0..1 + rng.below(16))
                    .map(|_| {
                        let b = rng.next() as u8;
                        if printable { b' ' + b % 95 } else { b }
                    })
                    .collect();
                data.splice(at..at, garbage);
            }
            6 if len > 0 => {
                let from = rng.below(len);
                let to = from + 1 + rng.below((len - from).min(64));
                data.drain(from..to);
            }
            7 if len > 0 => {
                // Repeat a range somewhere (a frame sent twice, a table written twice).
                let from = rng.below(len);
                let to = from + 1 + rng.below((len - from).min(128));
                let chunk = data[from..to].to_vec();
                let at = rng.cut(len);
                data.splice(at..at, chunk);
            }
            _ => {
                // Crossover: a range of another input inserted.
                let other = pool[rng.below(pool.len())];
                let from = rng.cut(other.len());
                let to = from + rng.below(other.len() - from + 1).min(128);
                let at = rng.cut(len);
                data.splice(at..at, other[from..to].iter().copied());
            }
        }
    }
    data.truncate(max_len);
    data
}
