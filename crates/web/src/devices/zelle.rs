//! The ZELLE cell's panel: measurements run by a worker thread, a chunk at a time so the plot
//! fills while the cell measures, and the data area in RAM as a hex listing. Each chunk is a
//! block of its own in the plot: between two blocks the cell did not measure (it was read
//! back), and a line drawn across that gap would show values nobody measured.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use buslab_link::SerialLine;
use buslab_zelle::analog::to_volts;
use buslab_zelle::client::{Client, SeriesParams, Transfer};
use buslab_zelle::timing::LINE;
use buslab_zelle::{DATA_AREA, PARAMS_LEN, hex_listing};
use serde::Serialize;

use super::{PANEL_PATIENCE, Version, lock};

/// Points kept per channel (the oldest go first).
const MAX_POINTS: usize = 1500;

/// One measured block of a channel: (seconds since the run started, volts).
pub type Block = Vec<(f64, f64)>;
/// Bytes of the data area the RAM view reads at most.
pub const MAX_RAM_VIEW: usize = 512;
/// A run's chunks at most (each a block of the series).
pub const MAX_CHUNKS: u32 = 100;

/// What the panel asks the worker for.
#[derive(Clone, Debug, PartialEq)]
pub enum ZelleJob {
    /// `chunks` series one after the other, each `cycles` scan cycles of `channels` every
    /// `interval_ms`, plotted as each one is read back.
    Measure { params: SeriesParams, chunks: u32 },
    /// The data area from 0800h, `len` bytes.
    ReadRam { len: usize },
}

/// Why the worker did not take a job.
#[derive(Debug, thiserror::Error)]
pub enum JobRefused {
    #[error("the {0} is busy ({1}): wait for it, or stop it")]
    Busy(&'static str, String),
    #[error("the {0}'s worker stopped")]
    Stopped(&'static str),
}

/// Changes the panel's state and tells the viewers.
type Set<'a> = &'a dyn Fn(&mut dyn FnMut(&mut ZelleState));

#[derive(Default)]
struct ZelleState {
    busy: Option<String>,
    channels: Vec<u8>,
    /// Per channel, its blocks, oldest first.
    series: Vec<VecDeque<Block>>,
    runs: u64,
    chunks_done: u64,
    missing: usize,
    ram: Option<String>,
    error: Option<String>,
}

/// The panel in JSON.
#[derive(Serialize)]
pub struct ZelleView {
    pub port: String,
    /// What the cell is doing, `None` when idle.
    pub busy: Option<String>,
    /// The channels of the last run and, per channel, its measured blocks, each a list of
    /// (seconds, volts): the cell measured nothing between two blocks.
    pub channels: Vec<u8>,
    pub series: Vec<Vec<Block>>,
    pub runs: u64,
    pub chunks: u64,
    /// Readings the cell should have given and did not (a block cut short).
    pub missing: usize,
    /// The data area as a hex listing.
    pub ram: Option<String>,
    pub error: Option<String>,
}

pub struct ZelleWorker {
    port: PathBuf,
    state: Arc<Mutex<ZelleState>>,
    jobs: Option<SyncSender<ZelleJob>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl ZelleWorker {
    pub fn spawn(port: PathBuf, version: Version) -> std::io::Result<Self> {
        let state = Arc::new(Mutex::new(ZelleState::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let (jobs, inbox) = mpsc::sync_channel(1);
        let thread = std::thread::Builder::new()
            .name("web-zelle".into())
            .spawn({
                let (state, stop, port) = (state.clone(), stop.clone(), port.clone());
                move || work(&port, &inbox, &state, &stop, &version)
            })?;
        Ok(Self {
            port,
            state,
            jobs: Some(jobs),
            stop,
            thread: Some(thread),
        })
    }

    /// Queues a job unless the cell is busy.
    pub fn submit(&self, job: ZelleJob) -> Result<(), JobRefused> {
        if let Some(busy) = lock(&self.state).busy.clone() {
            return Err(JobRefused::Busy("ZELLE cell", busy));
        }
        self.stop.store(false, Ordering::SeqCst);
        let jobs = self
            .jobs
            .as_ref()
            .ok_or(JobRefused::Stopped("ZELLE cell"))?;
        match jobs.try_send(job) {
            Ok(()) => Ok(()),
            Err(TrySendError::Full(_)) => {
                Err(JobRefused::Busy("ZELLE cell", "a job is queued".into()))
            }
            Err(TrySendError::Disconnected(_)) => Err(JobRefused::Stopped("ZELLE cell")),
        }
    }

    /// Ends a run after the chunk under way.
    pub fn stop_run(&self) {
        self.stop.store(true, Ordering::SeqCst);
    }

    pub fn view(&self) -> ZelleView {
        let s = lock(&self.state);
        ZelleView {
            port: self.port.display().to_string(),
            busy: s.busy.clone(),
            channels: s.channels.clone(),
            series: s
                .series
                .iter()
                .map(|blocks| blocks.iter().cloned().collect())
                .collect(),
            runs: s.runs,
            chunks: s.chunks_done,
            missing: s.missing,
            ram: s.ram.clone(),
            error: s.error.clone(),
        }
    }
}

impl Drop for ZelleWorker {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        drop(self.jobs.take());
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn work(
    port: &std::path::Path,
    inbox: &Receiver<ZelleJob>,
    state: &Mutex<ZelleState>,
    stop: &AtomicBool,
    version: &Version,
) {
    let set = |f: &mut dyn FnMut(&mut ZelleState)| {
        f(&mut lock(state));
        version.bump();
    };
    while let Ok(job) = inbox.recv() {
        set(&mut |s| {
            s.busy = Some("opening the port".into());
            s.error = None;
        });
        let result = SerialLine::open_when_free(port, LINE, PANEL_PATIENCE)
            .map_err(|e| format!("opening {}: {e}", port.display()))
            .and_then(|line| {
                let mut cell = Client::with_timeout(line, PANEL_PATIENCE);
                match &job {
                    ZelleJob::Measure { params, chunks } => {
                        measure(&mut cell, params, *chunks, stop, &set)?;
                        read_ram(
                            &mut cell,
                            8 + params.channels().len() * usize::from(params.cycles),
                            &set,
                        )
                    }
                    ZelleJob::ReadRam { len } => read_ram(&mut cell, *len, &set),
                }
            });
        set(&mut |s| {
            s.busy = None;
            if let Err(e) = &result {
                tracing::debug!("ZELLE panel: {e}");
                s.error = Some(e.clone());
            }
        });
    }
}

fn measure(
    cell: &mut Client<SerialLine>,
    params: &SeriesParams,
    chunks: u32,
    stop: &AtomicBool,
    set: Set<'_>,
) -> Result<(), String> {
    let channels = params.channels();
    set(&mut |s| {
        s.channels = channels.clone();
        s.series = vec![VecDeque::new(); channels.len()];
        s.runs += 1;
        s.chunks_done = 0;
        s.missing = 0;
    });
    let started = Instant::now();
    for chunk in 0..chunks {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        set(&mut |s| s.busy = Some(format!("measuring, block {} of {chunks}", chunk + 1)));
        let offset = started.elapsed().as_secs_f64();
        let m = cell.measure(params, 1, |_| {}).map_err(|e| e.to_string())?;
        set(&mut |s| {
            for (k, blocks) in s.series.iter_mut().enumerate() {
                let block = m
                    .rows
                    .iter()
                    .filter_map(|row| {
                        let value = row.values.get(k)?;
                        let t = offset + row.time_ns.get() as f64 * 1e-9 + k as f64 * 1e-3;
                        Some(((t * 1000.0).round() / 1000.0, to_volts(*value)))
                    })
                    .collect();
                keep_block(blocks, block, MAX_POINTS);
            }
            s.chunks_done += 1;
            s.missing += m.missing_values();
        });
    }
    Ok(())
}

/// Appends a channel's new block; the oldest points go once there are more than `max`.
fn keep_block(blocks: &mut VecDeque<Block>, block: Block, max: usize) {
    blocks.push_back(block);
    let mut excess = blocks
        .iter()
        .map(Vec::len)
        .sum::<usize>()
        .saturating_sub(max);
    while excess > 0 {
        let Some(oldest) = blocks.front_mut() else {
            break;
        };
        let cut = excess.min(oldest.len());
        oldest.drain(..cut);
        excess -= cut;
        if oldest.is_empty() {
            blocks.pop_front();
        }
    }
}

fn read_ram(cell: &mut Client<SerialLine>, len: usize, set: Set<'_>) -> Result<(), String> {
    let len = len.clamp(usize::from(PARAMS_LEN), MAX_RAM_VIEW);
    set(&mut |s| s.busy = Some(format!("reading {len} bytes of RAM from 0800h")));
    let data = cell
        .read_data(len, Transfer::Pipelined)
        .map_err(|e| e.to_string())?;
    let listing = hex_listing(DATA_AREA, &data);
    set(&mut |s| s.ram = Some(listing.clone()));
    Ok(())
}

/// How long a measurement job takes at least (for the refusal of absurd ones).
pub fn run_time(params: &SeriesParams, chunks: u32) -> Duration {
    params.block_ns().as_duration().saturating_mul(chunks)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(from: f64, n: usize) -> Block {
        (0..n).map(|i| (from + i as f64 * 0.01, 1.0)).collect()
    }

    #[test]
    fn blocks_stay_apart_and_the_oldest_points_go_first() {
        let mut blocks = VecDeque::new();
        keep_block(&mut blocks, block(0.0, 50), 120);
        keep_block(&mut blocks, block(0.8, 50), 120);
        assert_eq!(
            blocks.len(),
            2,
            "a block of its own, not joined to the last"
        );
        keep_block(&mut blocks, block(1.6, 50), 120);
        // 150 points, 120 kept: the first block lost its 30 oldest.
        assert_eq!(
            blocks.iter().map(Vec::len).collect::<Vec<_>>(),
            [20, 50, 50]
        );
        assert!((blocks[0][0].0 - 0.3).abs() < 1e-9, "{:?}", blocks[0][0]);
        keep_block(&mut blocks, block(2.4, 50), 120);
        assert_eq!(
            blocks.iter().map(Vec::len).collect::<Vec<_>>(),
            [20, 50, 50],
            "the emptied block is gone"
        );
        assert!((blocks[0][0].0 - 1.1).abs() < 1e-9, "{:?}", blocks[0][0]);
    }
}
