//! A shard's MAVLink I/O on a thread of its own: [`MavlinkThread`] carries the shard core's
//! queues to a [`ShardSockets`] that another thread owns, so building the due telemetry
//! ([`Outgoing::Telemetry`]), encoding it and the sends overlap the shard's next window.
//!
//! Why: with the I/O on the shard's thread, MAVLink took about a fifth of the shard's time
//! at 1024 drones, and the shard is the lockstep's critical
//! path. PX4 runs its mavlink module as a task of its own for the same reason.
//!
//! # Order and timing (what peers see)
//! The thread does the jobs in the order the shard gives them: every window's `send`, and
//! at an exchange the `receive`, which the shard waits for. So
//! - every frame leaves in the order, and with the sequence numbers, it would have on the
//!   shard's thread (the frames are the same: tested);
//! - at an exchange, what was queued before it has been encoded, and sent when flushed,
//!   before the sessions see what arrived: a reply still answers what peers sent by the
//!   previous exchange;
//! - the shard never runs more than one exchange ahead of its sockets (the `receive` waits),
//!   so a slow network shows as a slower shard, not as a queue that grows.
//!
//! Only when the frames of the last window leave changes: after the shard goes on, instead
//! of before. Nothing in the simulation depends on it (the simulation never reads its own
//! telemetry), so runs stay byte-identical.

use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;

use super::ShardSockets;
use crate::record::Lap;
use sadesim_engine::mavlink::frame::Frame;
use sadesim_engine::mavlink::session::Outgoing;
use sadesim_engine::shard::{MavlinkIo, MavlinkQueues};

/// What the shard asks of its I/O thread.
#[derive(Debug)]
enum Job {
    /// One window's outbound queues (index = drone), to encode; `flush`: then send.
    Send { outbound: Vec<Vec<Outgoing>>, flush: bool },
    /// Read what arrived; the answer is every drone's inbound frames (index = drone).
    Receive,
}

/// The shard's end of its MAVLink I/O thread (see the module docs).
#[derive(Debug)]
pub struct MavlinkThread {
    jobs: Option<Sender<Job>>,
    /// Answers to [`Job::Receive`].
    inbound: Receiver<Vec<Vec<Frame>>>,
    /// The thread gives the emptied outbound lists back, so their allocations are reused.
    spare: Receiver<Vec<Vec<Outgoing>>>,
    /// Returns the CPU seconds the thread used.
    handle: Option<JoinHandle<f64>>,
}

impl MavlinkThread {
    /// Moves `sockets` to a new thread named `name`.
    pub fn spawn(sockets: ShardSockets, name: String) -> Self {
        let (jobs, job_rx) = channel::<Job>();
        let (inbound_tx, inbound) = channel();
        let (spare_tx, spare) = channel();
        let handle = std::thread::Builder::new()
            .name(name)
            .spawn(move || serve(sockets, &job_rx, &inbound_tx, &spare_tx))
            .expect("the OS can start a thread");
        Self { jobs: Some(jobs), inbound, spare, handle: Some(handle) }
    }

    fn submit(&self, job: Job) {
        let sent = self.jobs.as_ref().is_some_and(|jobs| jobs.send(job).is_ok());
        if !sent {
            self.thread_failed();
        }
    }

    /// The thread is gone before its time: it panicked (the socket code's bug), which the
    /// shard cannot carry on without.
    fn thread_failed(&self) -> ! {
        panic!("the shard's MAVLink I/O thread stopped (see its panic message above)")
    }
}

/// The thread's loop: runs until the shard's end is dropped or finished, every job given
/// before that done (the last window's frames leave); returns the thread's CPU time, s.
fn serve(
    sockets: ShardSockets,
    jobs: &Receiver<Job>,
    inbound: &Sender<Vec<Vec<Frame>>>,
    spare: &Sender<Vec<Vec<Outgoing>>>,
) -> f64 {
    let mut lap = Lap::start();
    do_jobs(sockets, jobs, inbound, spare);
    let mut cpu_s = 0.0;
    lap.add_to(&mut cpu_s);
    cpu_s
}

fn do_jobs(
    mut sockets: ShardSockets,
    jobs: &Receiver<Job>,
    inbound: &Sender<Vec<Vec<Frame>>>,
    spare: &Sender<Vec<Vec<Outgoing>>>,
) {
    let mut queues: Vec<MavlinkQueues> = Vec::new();
    queues.resize_with(sockets.endpoints().len(), MavlinkQueues::default);
    while let Ok(job) = jobs.recv() {
        match job {
            Job::Send { mut outbound, flush } => {
                for (queue, list) in queues.iter_mut().zip(&mut outbound) {
                    std::mem::swap(&mut queue.outbound, list);
                }
                sockets.send(&mut queues, flush);
                // `outbound` now holds the lists the sockets emptied last time.
                let _ = spare.send(outbound);
            }
            Job::Receive => {
                sockets.receive(&mut queues);
                let frames = queues.iter_mut().map(|q| std::mem::take(&mut q.inbound)).collect();
                if inbound.send(frames).is_err() {
                    return;
                }
            }
        }
    }
}

impl MavlinkIo for MavlinkThread {
    /// Waits until the thread has done every earlier job and read its sockets.
    fn receive(&mut self, queues: &mut [MavlinkQueues]) {
        self.submit(Job::Receive);
        let Ok(frames) = self.inbound.recv() else { self.thread_failed() };
        for (queue, mut frames) in queues.iter_mut().zip(frames) {
            queue.inbound.append(&mut frames);
        }
    }

    /// Hands the outbound queues over (each drone's queue is left empty, with the
    /// allocation of a list the thread has finished with) and goes on at once.
    fn send(&mut self, queues: &mut [MavlinkQueues], flush: bool) {
        let mut outbound = self.spare.try_recv().unwrap_or_default();
        outbound.resize_with(queues.len(), Vec::new);
        for (queue, list) in queues.iter_mut().zip(&mut outbound) {
            list.clear();
            std::mem::swap(&mut queue.outbound, list);
        }
        self.submit(Job::Send { outbound, flush });
    }

    /// Lets the thread finish the jobs given so far (the last frames are sent), joins it
    /// and returns the CPU seconds it used (0 the second time).
    fn finish(&mut self) -> f64 {
        drop(self.jobs.take());
        self.handle.take().map_or(0.0, |handle| handle.join().unwrap_or(0.0))
    }
}

impl Drop for MavlinkThread {
    /// [`MavlinkIo::finish`], when the shard did not call it (an error ended the run).
    fn drop(&mut self) {
        self.finish();
    }
}
