//! The CPU196 board's panel: its identity, the THREAD text its program writes, and the A/D
//! stream as a live plot between a start and a stop, driven by a worker thread that is the
//! board's monitor (watchdog pings, the stream read and recorded) while it runs.

use std::collections::{BTreeMap, VecDeque};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, SyncSender, TryRecvError, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use buslab_cpu196::host::{Client, Monitor, Recorder, Sample, SampleSink};
use buslab_cpu196::message::Start;
use buslab_link::{LineSettings, SerialLine};
use serde::Serialize;

use super::zelle::JobRefused;
use super::{PANEL_PATIENCE, Version, lock};

/// Points kept per series (source and channel).
const MAX_POINTS: usize = 600;
/// Characters of THREAD text kept.
const MAX_TEXT: usize = 4000;
/// Series shown at most (the board has 8 + 8 + virtual channels).
const MAX_SERIES: usize = 24;
/// How long one monitor turn waits for the board.
const TURN: Duration = Duration::from_millis(20);

/// What the panel asks the worker for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cpu196Job {
    /// Read the identity (CPUINF).
    Identify,
    /// START configuration set `config` of bank `bank` (the 80C196 A/D on) and stream until
    /// [`Cpu196Job::Stop`].
    Start {
        bank: u8,
        config: u8,
    },
    Stop,
}

#[derive(Default)]
struct Cpu196State {
    identity: Option<String>,
    running: Option<String>,
    busy: bool,
    text: String,
    series: BTreeMap<String, VecDeque<(f64, f64)>>,
    samples: u64,
    error: Option<String>,
}

#[derive(Serialize)]
pub struct Cpu196View {
    pub port: String,
    pub identity: Option<String>,
    /// `bank B configuration C` while streaming.
    pub running: Option<String>,
    pub busy: bool,
    /// The THREAD text (the newest 4000 characters).
    pub text: String,
    /// Per source and channel (`c196 3`, `pic 0`): points (seconds, volts).
    pub series: Vec<(String, Vec<(f64, f64)>)>,
    pub samples: u64,
    pub error: Option<String>,
}

pub struct Cpu196Worker {
    port: PathBuf,
    state: Arc<Mutex<Cpu196State>>,
    jobs: Option<SyncSender<Cpu196Job>>,
    thread: Option<JoinHandle<()>>,
}

impl Cpu196Worker {
    /// Starts the worker, which reads the board's identity first.
    pub fn spawn(port: PathBuf, baud: u32, version: Version) -> io::Result<Self> {
        let state = Arc::new(Mutex::new(Cpu196State::default()));
        let (jobs, inbox) = mpsc::sync_channel(2);
        let _ = jobs.try_send(Cpu196Job::Identify);
        let thread = std::thread::Builder::new()
            .name("web-cpu196".into())
            .spawn({
                let (state, port) = (state.clone(), port.clone());
                move || work(&port, baud, &inbox, &state, &version)
            })?;
        Ok(Self {
            port,
            state,
            jobs: Some(jobs),
            thread: Some(thread),
        })
    }

    pub fn submit(&self, job: Cpu196Job) -> Result<(), JobRefused> {
        {
            let s = lock(&self.state);
            let streaming = s.running.is_some();
            match job {
                Cpu196Job::Stop if !streaming => {
                    return Err(JobRefused::Busy(
                        "CPU196 board",
                        "it is not streaming".into(),
                    ));
                }
                Cpu196Job::Identify | Cpu196Job::Start { .. } if streaming || s.busy => {
                    return Err(JobRefused::Busy(
                        "CPU196 board",
                        s.running.clone().unwrap_or_else(|| "a request".into()),
                    ));
                }
                _ => {}
            }
        }
        let jobs = self
            .jobs
            .as_ref()
            .ok_or(JobRefused::Stopped("CPU196 board"))?;
        match jobs.try_send(job) {
            Ok(()) => Ok(()),
            Err(TrySendError::Full(_)) => Err(JobRefused::Busy(
                "CPU196 board",
                "requests are queued".into(),
            )),
            Err(TrySendError::Disconnected(_)) => Err(JobRefused::Stopped("CPU196 board")),
        }
    }

    pub fn view(&self) -> Cpu196View {
        let s = lock(&self.state);
        Cpu196View {
            port: self.port.display().to_string(),
            identity: s.identity.clone(),
            running: s.running.clone(),
            busy: s.busy,
            text: s.text.clone(),
            series: s
                .series
                .iter()
                .map(|(k, v)| (k.clone(), v.iter().copied().collect()))
                .collect(),
            samples: s.samples,
            error: s.error.clone(),
        }
    }
}

impl Drop for Cpu196Worker {
    fn drop(&mut self) {
        // The worker stops a stream when its queue closes.
        drop(self.jobs.take());
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

type Set<'a> = &'a dyn Fn(&mut dyn FnMut(&mut Cpu196State));

fn work(
    port: &Path,
    baud: u32,
    inbox: &Receiver<Cpu196Job>,
    state: &Arc<Mutex<Cpu196State>>,
    version: &Version,
) {
    let set = |f: &mut dyn FnMut(&mut Cpu196State)| {
        f(&mut lock(state));
        version.bump();
    };
    while let Ok(job) = inbox.recv() {
        set(&mut |s| {
            s.busy = true;
            s.error = None;
        });
        let result = match job {
            Cpu196Job::Identify => open(port, baud).and_then(|mut c| {
                let info = c.info().map_err(|e| e.to_string())?;
                set(&mut |s| s.identity = Some(info.to_string()));
                Ok(())
            }),
            Cpu196Job::Start { bank, config } => {
                stream(port, baud, bank, config, inbox, state.clone(), &set)
            }
            // Stopping a stream that is not running: nothing to do.
            Cpu196Job::Stop => Ok(()),
        };
        set(&mut |s| {
            s.busy = false;
            s.running = None;
            if let Err(e) = &result {
                tracing::debug!("CPU196 panel: {e}");
                s.error = Some(e.clone());
            }
        });
    }
}

fn open(port: &Path, baud: u32) -> Result<Client<SerialLine>, String> {
    let line = SerialLine::open_when_free(port, LineSettings::n81(baud), PANEL_PATIENCE)
        .map_err(|e| format!("opening {}: {e}", port.display()))?;
    let mut c = Client::new(line, baud);
    c.timeout = PANEL_PATIENCE;
    // Whatever the board said before we came is not an answer (bounded: a running
    // acquisition never falls silent).
    let until = c.now() + Duration::from_millis(100);
    while c.now() < until && matches!(c.next(Duration::from_millis(30)), Ok(Some(_))) {}
    let _ = c.take_backlog();
    Ok(c)
}

fn stream(
    port: &Path,
    baud: u32,
    bank: u8,
    config: u8,
    inbox: &Receiver<Cpu196Job>,
    state: Arc<Mutex<Cpu196State>>,
    set: Set<'_>,
) -> Result<(), String> {
    let mut c = open(port, baud)?;
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let mut recorder = Recorder::new(Samples::new(state.clone()), c.now());
    match c.log_table() {
        Ok(t) => recorder.set_log_table(t),
        Err(e) => tracing::debug!("CPU196 panel: log table not read ({e}); log8 uses the default"),
    }
    let mut session = Monitor::new(None, Some(recorder), c.now());
    set(&mut |s| {
        s.series.clear();
        s.samples = 0;
        s.text.clear();
    });
    let started = session
        .start(&mut c, Start::run(bank, config, true))
        .map_err(|e| format!("START bank {bank} configuration {config}: {e}"))?;
    let what = if started.ad196() {
        format!("bank {bank} configuration {config}")
    } else {
        format!(
            "bank {bank} configuration {config} (no 80C196 A/D: the set has no conversion sequence)"
        )
    };
    set(&mut |s| s.running = Some(what.clone()));
    let mut out = String::new();
    let mut told = 0;
    loop {
        match inbox.try_recv() {
            Ok(Cpu196Job::Stop) | Err(TryRecvError::Disconnected) => break,
            // Refused by `submit` while streaming; nothing else is queued.
            Ok(_) | Err(TryRecvError::Empty) => {}
        }
        session.turn(&mut c, TURN, &mut out).map_err(|e| err(&e))?;
        if !out.is_empty() {
            set(&mut |s| append_text(&mut s.text, &out));
            out.clear();
        }
        let samples = lock(&state).samples;
        if samples != told {
            // Samples came in through the recorder: tell the viewers.
            told = samples;
            set(&mut |_| {});
        }
    }
    session.stop(&mut c, &mut out).map_err(|e| err(&e))?;
    set(&mut |s| append_text(&mut s.text, &out));
    session.finish().map_err(|e| err(&e))?;
    Ok(())
}

fn append_text(text: &mut String, more: &str) {
    text.push_str(more);
    if text.len() > MAX_TEXT {
        let mut cut = text.len() - MAX_TEXT;
        while !text.is_char_boundary(cut) {
            cut += 1;
        }
        text.drain(..cut);
    }
}

/// The recorder's samples turned into plot points, per source and channel.
struct Samples {
    state: Arc<Mutex<Cpu196State>>,
}

impl Samples {
    fn new(state: Arc<Mutex<Cpu196State>>) -> Self {
        Self { state }
    }
}

impl SampleSink for Samples {
    fn sample(&mut self, sample: &Sample) -> io::Result<()> {
        // Virtual channels have no volts: not plotted.
        let Some(volts) = sample.volts else {
            return Ok(());
        };
        let mut s = lock(&self.state);
        s.samples += 1;
        let key = format!("{} {}", sample.source, sample.channel);
        if !s.series.contains_key(&key) && s.series.len() >= MAX_SERIES {
            return Ok(());
        }
        let points = s.series.entry(key).or_default();
        if points.len() == MAX_POINTS {
            points.pop_front();
        }
        // What the page shows: 0.1 ms and 0.1 mV.
        let round = |x: f64| (x * 1e4).round() / 1e4;
        points.push_back((round(sample.t_s), round(volts)));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use buslab_cpu196::host::SampleSource;

    #[test]
    fn samples_become_points_per_channel_and_virtual_ones_are_not_plotted() {
        let state = Arc::new(Mutex::new(Cpu196State::default()));
        let mut s = Samples::new(state.clone());
        let c196 = |t_s, value, volts| Sample {
            t_s,
            source: SampleSource::C196,
            channel: 0,
            value,
            volts: Some(volts),
        };
        s.sample(&c196(0.001, 512.0, 2.500_04)).unwrap();
        s.sample(&c196(0.002_04, 1023.0, 5.0)).unwrap();
        s.sample(&Sample {
            t_s: 0.003,
            source: SampleSource::Virtual,
            channel: 1,
            value: 7.0,
            volts: None,
        })
        .unwrap();
        let st = lock(&state);
        assert_eq!(st.samples, 2);
        let points: Vec<_> = st.series["c196 0"].iter().copied().collect();
        assert_eq!(points, vec![(0.001, 2.5), (0.002, 5.0)]);
    }

    #[test]
    fn the_text_keeps_its_newest_characters() {
        let mut t = String::new();
        append_text(&mut t, &"é".repeat(3000));
        append_text(&mut t, "end");
        assert!(t.len() <= MAX_TEXT && t.ends_with("end"));
    }
}
