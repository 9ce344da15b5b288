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
//! - A write error stops the thread; the caller's next [`StreamWriter::write`] (or
//!   [`StreamWriter::finish`]) returns it.
//! - [`StreamWriter::finish`] waits until both files are complete. Dropped without it (the
//!   run ended on an error, or the caller unwinds), it does the same and drops the result.

use std::io;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

use super::cost::{Lap, RecordingCost};
use super::{CameraImage, McapRecorder, UlogRecorder};
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
    thread: Option<JoinHandle<io::Result<RecordingCost>>>,
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
        Ok(Self { sender: Some(sender), pending: Vec::with_capacity(BATCH_WINDOWS), thread: Some(thread) })
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
        match self.join() {
            Err(e) => Err(e),
            Ok(_) => Err(io::Error::other("the recording thread ended early")),
        }
    }

    /// Hands over the last windows, waits for them and the files' ends; the CPU time the
    /// thread spent on each file (`other`: freeing windows and its own bookkeeping).
    ///
    /// # Errors
    /// Any write or finish error of the thread.
    pub fn finish(mut self) -> io::Result<RecordingCost> {
        if !self.pending.is_empty() {
            self.hand_over()?;
        }
        self.sender = None; // closing the channel tells the thread to finish the files
        self.join()
    }

    fn join(&mut self) -> io::Result<RecordingCost> {
        let thread = self.thread.take().ok_or_else(|| io::Error::other("the recording thread was already joined"))?;
        thread.join().map_err(|_| io::Error::other("the recording thread panicked"))?
    }
}

impl Drop for StreamWriter {
    /// Dropped without [`StreamWriter::finish`] (the run ended on an error, or unwinds):
    /// hands over the pending windows and waits while the thread finishes the files, so
    /// what was recorded is complete on disk (errors are the caller's to have seen).
    fn drop(&mut self) {
        if let Some(sender) = self.sender.take() {
            if !self.pending.is_empty() {
                let _ = sender.send(std::mem::take(&mut self.pending));
            }
            drop(sender);
            let _ = self.join();
        }
    }
}

/// The thread: writes windows until the channel closes, then finishes the files. Returns
/// at the first error (dropping the receiver, which the sender notices).
fn write_all(
    batches: Receiver<Vec<Window>>,
    mut mcap: Option<McapRecorder>,
    mut ulog: Option<UlogRecorder>,
) -> io::Result<RecordingCost> {
    yield_to_the_lockstep();
    let mut cost = RecordingCost::default();
    let mut lap = Lap::start();
    for w in batches.into_iter().flatten() {
        if let Some(m) = &mut mcap {
            m.write_window(w.time_s, &w.drones, &w.events)?;
            m.write_images(w.time_s, &w.images)?;
            lap.add_to(&mut cost.mcap);
        }
        if let Some(u) = &mut ulog {
            u.write_window(w.time_s, &w.drones, &w.events)?;
            lap.add_to(&mut cost.ulog);
        }
        // Freeing the window is the thread's too.
        drop(w);
        lap.add_to(&mut cost.other);
    }
    lap.add_to(&mut cost.other);
    if let Some(m) = mcap {
        m.finish()?;
        lap.add_to(&mut cost.mcap);
    }
    if let Some(u) = ulog {
        u.finish()?;
        lap.add_to(&mut cost.ulog);
    }
    Ok(cost)
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
        writer.finish().unwrap();
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
        let cost = writer.finish().unwrap();
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

    /// A disk that fills up mid-run: the error reaches the caller at a later `write`, and
    /// `finish` does not pretend the files are complete. The first drone's ULog is
    /// `/dev/full`: its buffered writer fails at its first flush (the logs flush once per
    /// simulated second).
    #[test]
    fn a_write_error_on_the_thread_reaches_the_caller() {
        let plan = plan_of(run_with_groups(&[("a", 3)]).build());
        let dir = TempDir::new("streams-full");
        std::fs::create_dir_all(dir.0.join(ULOG_DIR)).unwrap();
        let first = format!("{}.ulg", plan.drones[0].name);
        std::os::unix::fs::symlink("/dev/full", dir.0.join(ULOG_DIR).join(first)).unwrap();
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
        assert!(error.to_string().contains("No space left on device"), "ENOSPC, not a stand-in: {error}");
        let again = writer.write(1.0, Vec::new(), Vec::new()).unwrap_err();
        assert!(again.to_string().contains("already closed after an error"), "{again}");
        assert!(writer.finish().is_err());
    }
}
