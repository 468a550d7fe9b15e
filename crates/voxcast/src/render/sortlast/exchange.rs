//! How the processes of a sort-last render talk: MPI in the command-line
//! tool, threads here.

use crate::error::{Error, Result};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Barrier, Mutex};
use std::time::Duration;

/// The messages compositing needs. Every process calls the same methods in
/// the same order; `tag` tells one round's messages from the next.
pub trait Exchange {
    /// This process, `0 .. size()`.
    fn rank(&self) -> usize;
    /// The number of processes.
    fn size(&self) -> usize;
    /// Sends `out[i]` to process `peers[i]` and returns the message each
    /// peer sent this process, in `peers` order. `peers` holds this process
    /// too; its `out` entry is not sent and its answer is empty.
    fn exchange(&self, tag: u32, peers: &[usize], out: Vec<Vec<f32>>) -> Result<Vec<Vec<f32>>>;
    /// Process 0 gets every process's `data`, in rank order (its own
    /// included); the others get `None`.
    fn gather(&self, tag: u32, data: Vec<f32>) -> Result<Option<Vec<Vec<f32>>>>;
    /// Returns when every process has called it (so that compositing is
    /// timed apart from waiting for the slowest render).
    fn barrier(&self) -> Result<()>;
}

/// One message: sender, tag, values.
type Message = (usize, u32, Vec<f32>);

/// Processes as threads of one program, joined by channels: for tests, and
/// to check the compositing without MPI. A receive that waits longer than
/// the timeout is an error, never a hang.
pub struct ThreadExchange {
    rank: usize,
    to: Vec<Sender<Message>>,
    from: Receiver<Message>,
    /// Messages that came before they were asked for.
    early: Mutex<Vec<Message>>,
    timeout: Duration,
    all: Arc<Barrier>,
}

impl ThreadExchange {
    /// `n` connected processes, one for each thread.
    pub fn group(n: usize) -> Vec<ThreadExchange> {
        let (tx, rx): (Vec<_>, Vec<_>) = (0..n).map(|_| channel()).unzip();
        let all = Arc::new(Barrier::new(n));
        rx.into_iter()
            .enumerate()
            .map(|(rank, from)| ThreadExchange {
                rank,
                to: tx.clone(),
                from,
                early: Mutex::new(Vec::new()),
                timeout: Duration::from_secs(60),
                all: all.clone(),
            })
            .collect()
    }

    fn send(&self, to: usize, tag: u32, data: Vec<f32>) -> Result<()> {
        self.to[to]
            .send((self.rank, tag, data))
            .map_err(|_| Error::invalid(format!("sort-last: process {to} has gone")))
    }

    fn receive(&self, from: usize, tag: u32) -> Result<Vec<f32>> {
        let mut early = self
            .early
            .lock()
            .map_err(|_| Error::invalid("sort-last: poisoned"))?;
        if let Some(i) = early.iter().position(|m| m.0 == from && m.1 == tag) {
            return Ok(early.swap_remove(i).2);
        }
        loop {
            match self.from.recv_timeout(self.timeout) {
                Ok(m) if m.0 == from && m.1 == tag => return Ok(m.2),
                Ok(m) => early.push(m),
                Err(RecvTimeoutError::Timeout) => {
                    return Err(Error::invalid(format!(
                        "sort-last: process {} waited {} s for process {from}",
                        self.rank,
                        self.timeout.as_secs()
                    )))
                }
                Err(RecvTimeoutError::Disconnected) => {
                    return Err(Error::invalid(format!(
                        "sort-last: process {from} has gone"
                    )))
                }
            }
        }
    }
}

impl Exchange for ThreadExchange {
    fn rank(&self) -> usize {
        self.rank
    }
    fn size(&self) -> usize {
        self.to.len()
    }
    fn exchange(&self, tag: u32, peers: &[usize], out: Vec<Vec<f32>>) -> Result<Vec<Vec<f32>>> {
        for (&p, v) in peers.iter().zip(out) {
            if p != self.rank {
                self.send(p, tag, v)?;
            }
        }
        peers
            .iter()
            .map(|&p| {
                if p == self.rank {
                    Ok(Vec::new())
                } else {
                    self.receive(p, tag)
                }
            })
            .collect()
    }
    fn gather(&self, tag: u32, data: Vec<f32>) -> Result<Option<Vec<Vec<f32>>>> {
        if self.rank != 0 {
            self.send(0, tag, data)?;
            return Ok(None);
        }
        let mut all = vec![data];
        for p in 1..self.size() {
            all.push(self.receive(p, tag)?);
        }
        Ok(Some(all))
    }
    fn barrier(&self) -> Result<()> {
        self.all.wait();
        Ok(())
    }
}
