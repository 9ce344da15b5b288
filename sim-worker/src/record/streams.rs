//! The high-rate recordings, `recording.mcap` and `ulog/*.ulg`, written on their own thread.
//!
//! Why a thread: the coordinator runs the lockstep loop, and every shard waits while it
//! handles a window. Encoding and compressing a window's poses (about 140-170 µs per drone
//! and simulated second for MCAP and ULog together, `docs/performance.md` "Recording cost")
//! is most of that handling; for a 1000-drone run it would stall every shard for about
//! 150 ms per simulated second. Handed to this thread, it
//! overlaps with the shards' next window instead. It costs as much CPU as before; it only
//! leaves the critical path.
//!
//! The cheap files (`events.jsonl`, `trajectory.csv`) stay on the caller's thread, written
//! before the loop goes on: a pilot started at the release window finds `pilotsReleased`
//! in `events.jsonl`.
//!
//! Guarantees:
//! - Windows are written in the order they are sent; the files are byte for byte what a
//!   synchronous writer produces.
//! - At most `(QUEUE_BATCHES + 1) x BATCH_WINDOWS` windows wait besides the one being
//!   written: a writer slower than the simulation slows the caller (backpressure), never
//!   grows memory. A process killed mid-run loses those windows (0.3 simulated seconds by
//!   default) besides the open MCAP chunk.
//! - A write error stops the thread; the caller's next [`StreamWriter::write`] returns it,
//!   naming the file. The thread hands its writers back rather than dropping them.
//! - [`StreamWriter::finish`] waits for the thread, then closes the files on the caller's
//!   thread, cutting each back to its last whole record first (after a write error, part
//!   of one may have reached the disk), and says which are not whole. Dropped without it
//!   (the run ended on an error, or the caller unwinds), it does the same and drops the
//!   result.

use std::io;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

use sadesim_evidence::archive::{FileState, IncompleteFile};

use super::cost::{Lap, RecordingCost};
use super::{CameraImage, MCAP_FILE, McapRecorder, UlogRecorder};
use sadesim_engine::events::Event;
use sadesim_engine::protocol::DroneSnapshot;

/// Windows handed over at once (10 ms of simulated time each by default): one wake-up of
/// the thread per batch, not per window. Per window, the hand-over (a futex wake and a
/// context switch on a busy machine) cost as much CPU as encoding ten drones.
pub const BATCH_WINDOWS: usize = 10;

/// Batches that may wait for the writer thread.
pub const QUEUE_BATCHES: usize = 2;

/// The recorder thread's nice value (Linux: 0 is the default, 19 the lowest priority).
pub const RECORDER_NICE: i32 = 10;

/// Lowers the calling thread's scheduling priority to [`RECORDER_NICE`]. The shards and the
/// coordinator are the run's critical path: at every window's barrier the whole run waits
/// for the slowest shard, so when this thread takes a core from one shard the others idle
/// at the barrier (on 2 cores with 2 shards, 12 % of the CPU went idle this way). At a
/// lower priority it writes while they wait instead. It cannot fall behind without bound:
/// at most [`QUEUE_BATCHES`] batches wait, then the coordinator waits for it. The files do
/// not depend on when they are written. Best effort: where the OS refuses, nothing changes.
fn yield_to_the_lockstep() {
    // On Linux the nice value is per thread, and `setpriority(PRIO_PROCESS, 0)` sets the
    // calling thread's.
    let _ = rustix::process::setpriority_process(None, RECORDER_NICE);
}

/// One sync window, as the recorder saw it.
#[derive(Debug)]
struct Window {
    time_s: f64,
    drones: Vec<DroneSnapshot>,
    events: Vec<Event>,
    /// Camera frames taken in the window (`recording.mcap` only).
    images: Vec<CameraImage>,
}

/// The MCAP and ULog writers, on a thread of their own.
#[derive(Debug)]
pub struct StreamWriter {
    /// `None` once the thread is known to have ended.
    sender: Option<SyncSender<Vec<Window>>>,
    /// Windows not handed over yet (fewer than [`BATCH_WINDOWS`]).
    pending: Vec<Window>,
    thread: Option<JoinHandle<Written>>,
    /// What the thread handed back once it ended (on a write error, before
    /// [`StreamWriter::finish`]).
    ended: Option<Written>,
}

/// What the thread hands back when it ends: the writers, to be closed on the caller's
/// thread, and the first write error with the simulated time of its window.
#[derive(Debug)]
struct Written {
    cost: RecordingCost,
    mcap: Option<McapRecorder>,
    ulog: Option<UlogRecorder>,
    failed: Option<(f64, io::Error)>,
}

/// [`StreamWriter::finish`]'s account: the CPU time the files cost, the first write error
/// (naming the file) and the files that are not whole.
#[derive(Debug, Default)]
pub struct StreamsClosed {
    pub cost: RecordingCost,
    /// The write error that stopped the recording, with the simulated time of its window.
    pub failed: Option<(f64, io::Error)>,
    /// A file that could not be closed whole (no room even after the error): the first.
    pub close_error: Option<io::Error>,
    /// Per file that is not whole (the recording stopped early, or its end could not be
    /// written): path, state, detail. `detail` says what it holds.
    pub incomplete: Vec<IncompleteFile>,
}

impl StreamsClosed {
    /// The cost, when every file was written whole.
    ///
    /// # Errors
    /// The write error that stopped the recording, else the first file that could not be
    /// closed.
    pub fn whole(self) -> io::Result<RecordingCost> {
        match (self.failed, self.close_error) {
            (Some((_, e)), _) | (None, Some(e)) => Err(e),
            (None, None) => Ok(self.cost),
        }
    }
}

impl StreamWriter {
    /// Starts the thread that owns `mcap` and `ulog` (either may be off).
    ///
    /// # Errors
    /// The thread cannot be spawned.
    pub fn start(mcap: Option<McapRecorder>, ulog: Option<UlogRecorder>) -> io::Result<Self> {
        let (sender, receiver) = sync_channel(QUEUE_BATCHES);
        let thread =
            std::thread::Builder::new().name("recorder".into()).spawn(move || write_all(receiver, mcap, ulog))?;
        Ok(Self { sender: Some(sender), pending: Vec::with_capacity(BATCH_WINDOWS), thread: Some(thread), ended: None })
    }

    /// Queues a window; every [`BATCH_WINDOWS`] windows, hands them to the thread, blocking
    /// while [`QUEUE_BATCHES`] batches wait.
    ///
    /// # Errors
    /// The writer thread failed (on an earlier window): its error.
    pub fn write(&mut self, time_s: f64, drones: Vec<DroneSnapshot>, events: Vec<Event>) -> io::Result<()> {
        self.write_with_images(time_s, drones, events, Vec::new())
    }

    /// [`Self::write`] with the camera frames taken in the window.
    ///
    /// # Errors
    /// As [`Self::write`].
    pub fn write_with_images(
        &mut self,
        time_s: f64,
        drones: Vec<DroneSnapshot>,
        events: Vec<Event>,
        images: Vec<CameraImage>,
    ) -> io::Result<()> {
        if self.sender.is_none() {
            return Err(io::Error::other("the recordings were already closed after an error"));
        }
        self.pending.push(Window { time_s, drones, events, images });
        if self.pending.len() < BATCH_WINDOWS { Ok(()) } else { self.hand_over() }
    }

    /// Sends the pending windows.
    fn hand_over(&mut self) -> io::Result<()> {
        let Some(sender) = &self.sender else {
            return Err(io::Error::other("the recordings were already closed after an error"));
        };
        let batch = std::mem::replace(&mut self.pending, Vec::with_capacity(BATCH_WINDOWS));
        if sender.send(batch).is_ok() {
            return Ok(());
        }
        // The receiver is gone: the thread ended, which it does only on an error.
        self.sender = None;
        let mut written = self.join();
        // The caller gets the thread's error (it names the file), `finish` a copy.
        let error = match written.failed.take() {
            Some((time_s, e)) => {
                written.failed = Some((time_s, io::Error::new(e.kind(), e.to_string())));
                e
            }
            None => io::Error::other("the recording thread ended early"),
        };
        self.ended = Some(written);
        Err(error)
    }

    /// Hands over the last windows, waits for them, then closes the files: the CPU time
    /// the thread spent on each file (`other`: freeing windows and its own bookkeeping),
    /// and what is not whole.
    pub fn finish(self) -> StreamsClosed {
        self.finish_stopped(None)
    }

    /// [`Self::finish`] for a recording the caller stopped at `stopped_at_s` (simulated
    /// seconds) on a write error of its own: every file is then listed as ending there.
    pub fn finish_stopped(mut self, stopped_at_s: Option<f64>) -> StreamsClosed {
        if self.sender.is_some() && !self.pending.is_empty() {
            // An error here leaves the thread's account in `ended`.
            let _ = self.hand_over();
        }
        self.sender = None; // closing the channel tells the thread to stop
        let written = match self.ended.take() {
            Some(written) => written,
            None => self.join(),
        };
        close(written, stopped_at_s)
    }

    /// Waits for the thread's account (a panic of the thread is a write error of the run).
    fn join(&mut self) -> Written {
        let Some(thread) = self.thread.take() else {
            return Written {
                cost: RecordingCost::default(),
                mcap: None,
                ulog: None,
                failed: Some((0.0, io::Error::other("the recording thread was already joined"))),
            };
        };
        thread.join().unwrap_or_else(|_| Written {
            cost: RecordingCost::default(),
            mcap: None,
            ulog: None,
            failed: Some((0.0, io::Error::other("the recording thread panicked"))),
        })
    }
}

impl Drop for StreamWriter {
    /// Dropped without [`StreamWriter::finish`] (the run ended on an error, or unwinds):
    /// hands over the pending windows and waits for the thread, then closes the files, so
    /// what was recorded is complete on disk (errors are the caller's to have seen).
    fn drop(&mut self) {
        if let Some(sender) = self.sender.take() {
            if !self.pending.is_empty() {
                let _ = sender.send(std::mem::take(&mut self.pending));
            }
            drop(sender);
        }
        if self.thread.is_some() || self.ended.is_some() {
            let written = match self.ended.take() {
                Some(written) => written,
                None => self.join(),
            };
            close(written, None);
        }
    }
}

/// Closes the files the thread handed back, on the caller's thread ([`StreamWriter::finish`]).
fn close(written: Written, stopped_at_s: Option<f64>) -> StreamsClosed {
    let Written { mut cost, mcap, ulog, failed } = written;
    let mut lap = Lap::start();
    let mut closed = StreamsClosed { failed: None, ..Default::default() };
    let stopped = failed
        .as_ref()
        .map(|(time_s, _)| *time_s)
        .or(stopped_at_s)
        .map(|time_s| format!("it ends at {time_s:.2} s of simulated time, where the recording stopped"));
    let note = |closed: &mut StreamsClosed, path: &str, result: io::Result<Option<String>>| {
        let (state, detail) = match (result, &stopped) {
            (Ok(None), None) => return,
            (Ok(None), Some(stopped)) => (FileState::Truncated, format!("{stopped}; every record in it is whole")),
            (Ok(Some(lost)), stopped) => (
                FileState::Truncated,
                format!("{}; closed without {lost}", stopped.as_deref().unwrap_or("its end could not be written")),
            ),
            (Err(e), _) => {
                let detail = format!(
                    "{}; its end could not be written ({e}): it stops after its last whole record",
                    stopped.as_deref().unwrap_or("the run ended")
                );
                closed.close_error.get_or_insert(super::disk::named(path, e));
                (FileState::NotFinalised, detail)
            }
        };
        closed.incomplete.push(IncompleteFile { path: path.to_string(), state, detail });
    };
    if let Some(m) = mcap {
        let result = m.close().map_err(|e| super::disk::named(MCAP_FILE, e));
        note(&mut closed, MCAP_FILE, result);
        lap.add_to(&mut cost.mcap);
    }
    if let Some(u) = ulog {
        for (path, result) in u.close() {
            note(&mut closed, &path, result.map(|()| None));
        }
        lap.add_to(&mut cost.ulog);
    }
    closed.cost = cost;
    closed.failed = failed;
    closed
}

/// The thread: writes windows until the channel closes or a write fails, then hands the
/// writers back (closing them is the caller's, [`StreamWriter::finish`]). At the first
/// error it stops (dropping the receiver, which the sender notices).
fn write_all(
    batches: Receiver<Vec<Window>>,
    mut mcap: Option<McapRecorder>,
    mut ulog: Option<UlogRecorder>,
) -> Written {
    yield_to_the_lockstep();
    let mut cost = RecordingCost::default();
    let mut lap = Lap::start();
    let mut failed = None;
    for w in batches.into_iter().flatten() {
        if let Some(m) = &mut mcap {
            let written =
                m.write_window(w.time_s, &w.drones, &w.events).and_then(|()| m.write_images(w.time_s, &w.images));
            if let Err(e) = written {
                failed = Some((w.time_s, super::disk::named(MCAP_FILE, e)));
                break;
            }
            lap.add_to(&mut cost.mcap);
        }
        if let Some(u) = &mut ulog {
            // The ULog recorder names the drone's file.
            if let Err(e) = u.write_window(w.time_s, &w.drones, &w.events) {
                failed = Some((w.time_s, e));
                break;
            }
            lap.add_to(&mut cost.ulog);
        }
        // Freeing the window is the thread's too.
        drop(w);
        lap.add_to(&mut cost.other);
    }
    lap.add_to(&mut cost.other);
    Written { cost, mcap, ulog, failed }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::test_dir::TempDir;
    use crate::record::{MCAP_FILE, ULOG_DIR};
    use sadesim_engine::fixtures::{plan_of, run_with_groups, world_of};

    fn windows() -> impl Iterator<Item = (f64, Vec<DroneSnapshot>)> {
        (1..=200u32).map(|w| {
            let t = f64::from(w) * 0.01;
            (t, (0..3).map(|index| DroneSnapshot::climbing(index, f64::from(index) * 10.0, t)).collect())
        })
    }

    fn bytes(dir: &TempDir) -> Vec<(String, Vec<u8>)> {
        let mut files = vec![(MCAP_FILE.to_string(), std::fs::read(dir.0.join(MCAP_FILE)).unwrap())];
        let mut ulogs: Vec<_> = std::fs::read_dir(dir.0.join(ULOG_DIR)).unwrap().map(|e| e.unwrap().path()).collect();
        ulogs.sort();
        files.extend(ulogs.into_iter().map(|p| (p.display().to_string(), std::fs::read(p).unwrap())));
        files.iter_mut().for_each(|(name, _)| *name = name.rsplit('/').next().unwrap().to_string());
        files
    }

    /// The nice value in a Linux `/proc/.../stat` line (field 19; the fields after the
    /// command name, which ends at the last ')', start at field 3).
    fn nice_in_stat(stat: &str) -> i32 {
        let fields: Vec<&str> = stat.rsplit_once(')').unwrap().1.split_whitespace().collect();
        fields[19 - 3].parse().unwrap()
    }

    /// Nice values of this process's threads named `name` (`/proc/self/task/*`).
    fn nice_of_threads(name: &str) -> Vec<i32> {
        let mut nice = Vec::new();
        for task in std::fs::read_dir("/proc/self/task").unwrap().flatten() {
            let comm = std::fs::read_to_string(task.path().join("comm")).unwrap_or_default();
            if comm.trim_end() != name {
                continue;
            }
            nice.push(nice_in_stat(&std::fs::read_to_string(task.path().join("stat")).unwrap()));
        }
        nice
    }

    #[test]
    fn the_recorder_thread_yields_the_cores_to_the_lockstep() {
        let writer = StreamWriter::start(None, None).unwrap();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
        // The thread lowers its own priority as it starts.
        while !nice_of_threads("recorder").contains(&RECORDER_NICE) {
            assert!(std::time::Instant::now() < deadline, "recorder threads' nice: {:?}", nice_of_threads("recorder"));
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        assert!(!nice_of_threads("recorder").is_empty());
        // The caller's thread (a coordinator's) keeps its priority.
        assert_ne!(nice_in_stat(&std::fs::read_to_string("/proc/thread-self/stat").unwrap()), RECORDER_NICE);
        writer.finish().whole().unwrap();
    }

    #[test]
    fn the_thread_writes_the_same_bytes_as_the_writers_themselves() {
        let plan = plan_of(run_with_groups(&[("a", 3)]).build());
        let direct = TempDir::new("streams-direct");
        let (mut mcap, mut ulog) = (
            McapRecorder::create(&direct.0, &plan, &world_of(&plan), &[]).unwrap(),
            UlogRecorder::create(&direct.0, &plan).unwrap(),
        );
        for (t, drones) in windows() {
            mcap.write_window(t, &drones, &[]).unwrap();
            ulog.write_window(t, &drones, &[]).unwrap();
        }
        mcap.finish().unwrap();
        ulog.finish().unwrap();

        let threaded = TempDir::new("streams-threaded");
        let mcap = McapRecorder::create(&threaded.0, &plan, &world_of(&plan), &[]).unwrap();
        let ulog = UlogRecorder::create(&threaded.0, &plan).unwrap();
        let mut writer = StreamWriter::start(Some(mcap), Some(ulog)).unwrap();
        for (t, drones) in windows() {
            writer.write(t, drones, Vec::new()).unwrap();
        }
        let cost = writer.finish().whole().unwrap();
        assert!(cost.mcap > 0.0 && cost.ulog > 0.0, "{cost:?}");

        let (a, b) = (bytes(&direct), bytes(&threaded));
        assert_eq!(a.len(), 4, "the MCAP and 3 ULogs");
        assert_eq!(a.iter().map(|f| &f.0).collect::<Vec<_>>(), b.iter().map(|f| &f.0).collect::<Vec<_>>());
        for ((name, x), (_, y)) in a.iter().zip(&b) {
            assert!(x == y, "{name} differs");
        }
    }

    /// A writer dropped mid-batch (the run ended on an error) still writes every window it
    /// was given and completes the files.
    #[test]
    fn dropping_the_writer_keeps_every_window_and_completes_the_files() {
        let plan = plan_of(run_with_groups(&[("a", 3)]).build());
        let dir = TempDir::new("streams-dropped");
        let mut writer =
            StreamWriter::start(Some(McapRecorder::create(&dir.0, &plan, &world_of(&plan), &[]).unwrap()), None)
                .unwrap();
        let sent = BATCH_WINDOWS * 3 + 7; // the last 7 are still pending
        for (t, drones) in windows().take(sent) {
            writer.write(t, drones, Vec::new()).unwrap();
        }
        drop(writer);
        let poses = crate::record::mcap_file::finished_pose_count(&dir.0);
        assert_eq!(poses, 3 * sent as u64, "100 Hz ground truth: one pose per drone and window");
    }

    /// A disk that fills up mid-run: the error reaches the caller at a later `write`,
    /// naming the file, and `finish` says which files are not whole rather than pretending
    /// they are complete. The first drone's ULog is `/dev/full`: its buffered writer fails
    /// at its first flush (the logs flush once per simulated second), and no room ever
    /// comes back for it; the other drones' files close whole, ending where the recording
    /// stopped.
    #[test]
    fn a_write_error_on_the_thread_reaches_the_caller() {
        let plan = plan_of(run_with_groups(&[("a", 3)]).build());
        let dir = TempDir::new("streams-full");
        std::fs::create_dir_all(dir.0.join(ULOG_DIR)).unwrap();
        let first = format!("{}.ulg", plan.drones[0].name);
        std::os::unix::fs::symlink("/dev/full", dir.0.join(ULOG_DIR).join(&first)).unwrap();
        let ulog = UlogRecorder::create(&dir.0, &plan).unwrap();
        let mut writer = StreamWriter::start(None, Some(ulog)).unwrap();
        let mut error = None;
        for w in 1..=100_000u32 {
            let t = f64::from(w) * 0.01;
            let drones = (0..3).map(|index| DroneSnapshot::climbing(index, 0.0, t)).collect();
            if let Err(e) = writer.write(t, drones, Vec::new()) {
                error = Some(e);
                break;
            }
        }
        let error = error.expect("writing to /dev/full fails within 1000 simulated seconds");
        let path = format!("{ULOG_DIR}/{first}");
        assert_eq!(error.to_string(), format!("{path}: No space left on device (os error 28)"), "ENOSPC, named");
        assert_eq!(crate::record::disk::failed_file(&error), Some(path.as_str()));
        let again = writer.write(1.0, Vec::new(), Vec::new()).unwrap_err();
        assert!(again.to_string().contains("already closed after an error"), "{again}");
        let closed = writer.finish();
        let (stopped_at_s, failed) = closed.failed.expect("the write error");
        assert!(failed.to_string().starts_with(&path), "{failed}");
        assert!(closed.close_error.is_some(), "/dev/full never has room: its file cannot be closed");
        let states: Vec<(&str, FileState)> = closed.incomplete.iter().map(|f| (f.path.as_str(), f.state)).collect();
        let others: Vec<String> = plan.drones[1..].iter().map(|d| format!("{ULOG_DIR}/{}.ulg", d.name)).collect();
        assert_eq!(
            states,
            vec![
                (path.as_str(), FileState::NotFinalised),
                (others[0].as_str(), FileState::Truncated),
                (others[1].as_str(), FileState::Truncated)
            ]
        );
        assert!(
            closed.incomplete[1].detail.contains(&format!("ends at {stopped_at_s:.2} s")),
            "{:?}",
            closed.incomplete
        );
        // The closed files end on a whole message: the last one is the 1-second flush's.
        let bytes = std::fs::read(dir.0.join(&others[0])).unwrap();
        assert!(bytes.len() > 1000 && bytes.starts_with(b"ULog"));
    }
}
