//! Phases that spend their time waiting on the wall clock, not computing, run side by side.
//!
//! The real-time MavLora phases are sessions of programs over their own ptys and radio
//! emulators, each mostly waiting for seconds of scripted flight; one after the other they
//! take minutes of a 2-core machine that sits idle. A [`SideBySide`] group starts every
//! *selected* phase of the group (at most `width` at once, in order) when the first of its
//! trials runs, and each trial then waits for its own phase's record. Trials still report
//! in order, one record per phase, and a filter that selects one phase runs only that one.
//!
//! Only phases that share nothing may join a group: no device, no port, no fixed UDP port.
//! Children are started from the group's worker threads, which live until their phase has
//! stopped every program it started (the children's `PR_SET_PDEATHSIG` is tied to the
//! thread that started them).

use std::collections::{BTreeSet, VecDeque};
use std::sync::{Arc, Condvar, Mutex, OnceLock};

use crate::record::PhaseRecord;

type Job = Box<dyn FnOnce() -> PhaseRecord + Send>;

/// A group of phases run side by side.
pub struct SideBySide {
    width: usize,
    /// The group's phases, by name, in the order they were added.
    jobs: Mutex<Vec<(String, Option<Job>)>>,
    /// Names the run's filter selected; set once the run knows them.
    selected: OnceLock<BTreeSet<String>>,
    started: Mutex<bool>,
    results: Mutex<Vec<(String, PhaseRecord)>>,
    done: Condvar,
}

impl SideBySide {
    /// A group running at most `width` (≥ 1) phases at once.
    pub fn new(width: usize) -> Arc<SideBySide> {
        Arc::new(SideBySide {
            width: width.max(1),
            jobs: Mutex::new(Vec::new()),
            selected: OnceLock::new(),
            started: Mutex::new(false),
            results: Mutex::new(Vec::new()),
            done: Condvar::new(),
        })
    }

    /// Adds phase `name`; returns what its trial runs: start the group if no trial of it
    /// has, then wait for this phase's record.
    pub fn add(
        self: &Arc<Self>,
        name: String,
        job: impl FnOnce() -> PhaseRecord + Send + 'static,
    ) -> impl FnOnce() -> PhaseRecord + Send + 'static {
        self.jobs
            .lock()
            .unwrap()
            .push((name.clone(), Some(Box::new(job))));
        let group = self.clone();
        move || group.record_of(&name)
    }

    /// Which phases of the group the run selected (its filter); until this is called, every
    /// phase counts as selected.
    pub fn select<'a>(&self, names: impl IntoIterator<Item = &'a str>) {
        let _ = self
            .selected
            .set(names.into_iter().map(str::to_string).collect());
    }

    fn record_of(self: &Arc<Self>, name: &str) -> PhaseRecord {
        self.start();
        let mut results = self.results.lock().unwrap();
        loop {
            if let Some(i) = results.iter().position(|(n, _)| n == name) {
                return results.swap_remove(i).1;
            }
            results = self.done.wait(results).unwrap();
        }
    }

    /// Starts the workers once: they take the selected phases in order.
    fn start(self: &Arc<Self>) {
        let mut started = self.started.lock().unwrap();
        if *started {
            return;
        }
        *started = true;
        let queue: VecDeque<(String, Job)> = self
            .jobs
            .lock()
            .unwrap()
            .iter_mut()
            .filter(|(name, _)| self.selected.get().is_none_or(|s| s.contains(name)))
            .filter_map(|(name, job)| job.take().map(|j| (name.clone(), j)))
            .collect();
        let workers = self.width.min(queue.len());
        let queue = Arc::new(Mutex::new(queue));
        for k in 0..workers {
            let (group, mine) = (self.clone(), queue.clone());
            let spawned = std::thread::Builder::new()
                .name(format!("side-by-side-{k}"))
                .spawn(move || {
                    loop {
                        let next = mine.lock().unwrap().pop_front();
                        let Some((name, job)) = next else { break };
                        let record = run(&name, job);
                        group.results.lock().unwrap().push((name, record));
                        group.done.notify_all();
                    }
                });
            if let Err(e) = spawned {
                // No worker: the phases still run, one after the other, on this thread.
                tracing::warn!(error = %e, "cannot start a side-by-side worker");
                loop {
                    let next = queue.lock().unwrap().pop_front();
                    let Some((name, job)) = next else { break };
                    let record = run(&name, job);
                    self.results.lock().unwrap().push((name, record));
                }
            }
        }
    }
}

/// Runs one phase; a panic that escaped it still gives its trial a record, so no trial
/// waits for ever.
fn run(name: &str, job: Job) -> PhaseRecord {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(job)).unwrap_or_else(|payload| {
        PhaseRecord::ran(
            name,
            crate::record::now_rfc3339(),
            0.0,
            Vec::new(),
            Some(super::phase::panicked(payload.as_ref())),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::time::Duration;

    fn record(name: &str) -> PhaseRecord {
        PhaseRecord::ran(name, String::new(), 0.0, Vec::new(), None)
    }

    #[test]
    fn selected_phases_overlap_up_to_the_width_and_each_trial_gets_its_own_record() {
        let group = SideBySide::new(2);
        let running = Arc::new(AtomicUsize::new(0));
        let peak = Arc::new(AtomicUsize::new(0));
        let ran = Arc::new(Mutex::new(Vec::new()));
        let mut trials = Vec::new();
        for name in ["a", "b", "c", "skipped"] {
            let (running, peak, ran) = (running.clone(), peak.clone(), ran.clone());
            trials.push((
                name,
                group.add(name.to_string(), move || {
                    let now = running.fetch_add(1, Ordering::SeqCst) + 1;
                    peak.fetch_max(now, Ordering::SeqCst);
                    std::thread::sleep(Duration::from_millis(200));
                    running.fetch_sub(1, Ordering::SeqCst);
                    ran.lock().unwrap().push(name);
                    record(name)
                }),
            ));
        }
        group.select(["a", "b", "c"]);
        for (name, trial) in trials.into_iter().filter(|(n, _)| *n != "skipped") {
            assert_eq!(trial().name, name);
        }
        // They overlapped, never more than 2 at once.
        assert_eq!(peak.load(Ordering::SeqCst), 2);
        let mut ran = ran.lock().unwrap().clone();
        ran.sort();
        assert_eq!(ran, ["a", "b", "c"], "the unselected phase never runs");
    }
}
