//! Scenario files (TOML): bit rate, duration, seed, nodes with their options and traffic, and
//! faults with start and end. See `docs/sim.md` for the format. [`Scenario::build`] puts the
//! nodes on the one bus engine, made by the node factory ([`crate::nodes`]).

use buslab_can::controller::ControllerConfig;
use buslab_can::{Frame, Id, Nanos};
use buslab_sim::{BitTime, Fault, FaultKind, Simulation, Span, Traffic};
use buslab_slio::SlioId;
use serde::Deserialize;

use crate::error::ScenarioError;
use crate::nodes::{self, Sja1000Spec};

/// The longest a simulation may run, in virtual time (a `u64::MAX` duration ran for hours).
pub const MAX_DURATION: Nanos = Nanos::from_secs(3600);

/// [`MAX_DURATION`] in bit-times at `bitrate`.
pub fn max_duration(bitrate: u32) -> BitTime {
    MAX_DURATION.bit_times_at(bitrate)
}

/// Largest file a scenario may send (16 MiB).
const MAX_FILE: usize = 16 << 20;

/// A checked scenario, ready to [`Scenario::build`].
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    pub bitrate: u32,
    pub duration: BitTime,
    pub seed: u64,
    /// Interval of the TEC/REC series, if any.
    pub sample_every: Option<BitTime>,
    pub nodes: Vec<NodeSpec>,
    pub faults: Vec<Fault>,
}

/// A node of a scenario.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeSpec {
    pub name: String,
    pub kind: NodeKind,
    pub traffic: Vec<Traffic>,
}

/// What a scenario node is.
#[derive(Clone, Debug, PartialEq)]
pub enum NodeKind {
    /// A bare protocol controller with these options.
    Controller(ControllerConfig),
    /// A P82C150 SLIO on the seed's demo board, ID switches set to `id`; ADC1 (P5) and the
    /// potentiometer (P6) at constant voltages.
    Slio {
        id: SlioId,
        adc1: f64,
        potentiometer: f64,
    },
    /// An SJA1000 operated by the host library's driver (the CPU that services it), at the
    /// bus's bit rate.
    Sja1000(Sja1000Spec),
}

impl Scenario {
    /// Parses and checks a scenario; errors name the offending value.
    pub fn from_toml(text: &str) -> Result<Self, ScenarioError> {
        let raw: RawScenario = toml::from_str(text)?;
        raw.resolve()
    }

    /// A simulation set up as described, at time 0, its nodes made by the node factory
    /// ([`crate::nodes`]).
    pub fn build(&self) -> Result<Simulation, ScenarioError> {
        let mut sim = Simulation::new(self.bitrate, self.seed);
        for node in &self.nodes {
            let index = match &node.kind {
                NodeKind::Sja1000(spec) => {
                    let device =
                        nodes::sja1000(spec, self.bitrate).map_err(|why| ScenarioError::Node {
                            node: node.name.clone(),
                            why,
                        })?;
                    sim.add_device(&node.name, Box::new(device))
                }
                NodeKind::Controller(config) => sim.add_node(&node.name, *config),
                NodeKind::Slio {
                    id,
                    adc1,
                    potentiometer,
                } => {
                    // The bit rate was checked when the scenario was read.
                    let board = nodes::slio_board(*id, self.bitrate, *adc1, *potentiometer)
                        .expect("bit rate checked");
                    sim.add_device(&node.name, Box::new(crate::board::on_bus(board)))
                }
            };
            for t in &node.traffic {
                sim.add_traffic(index, t.clone());
            }
        }
        for fault in &self.faults {
            sim.add_fault(fault.clone());
        }
        if let Some(every) = self.sample_every {
            sim.sample_counters_every(every);
        }
        Ok(sim)
    }

    /// A one-line description of fault `index`, e.g. `cut [sender] error_rate 0.05`.
    pub fn describe_fault(&self, index: usize) -> String {
        let fault = &self.faults[index];
        let names = |list: &[usize]| {
            list.iter()
                .map(|&n| self.nodes[n].name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        };
        match &fault.kind {
            FaultKind::Disconnect { node } => format!("disconnect {}", self.nodes[*node].name),
            FaultKind::Cut {
                far_side,
                error_rate,
            } => format!(
                "cut, far side [{}], error rate {error_rate}",
                names(far_side)
            ),
            FaultKind::Flip { node: Some(n) } => format!("flip at {}", self.nodes[*n].name),
            FaultKind::Flip { node: None } => "flip at every node".to_owned(),
            FaultKind::StuckDominant => "stuck dominant".to_owned(),
            FaultKind::Noise { nodes, rate } if nodes.is_empty() => {
                format!("noise on the bus, rate {rate}")
            }
            FaultKind::Noise { nodes, rate } => format!("noise at [{}], rate {rate}", names(nodes)),
        }
    }
}

/// A duration as written: an integer (bit-times) or a string with a unit.
#[derive(Clone, Debug, PartialEq)]
struct RawSpan(String);

impl<'de> Deserialize<'de> for RawSpan {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = RawSpan;
            fn expecting(&self, f: &mut core::fmt::Formatter) -> core::fmt::Result {
                f.write_str("a duration: an integer (bit-times) or a string like \"10ms\"")
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<RawSpan, E> {
                Ok(RawSpan(v.to_string()))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<RawSpan, E> {
                Ok(RawSpan(v.to_string()))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<RawSpan, E> {
                Ok(RawSpan(v.to_owned()))
            }
        }
        d.deserialize_any(Visitor)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    bitrate: Option<u64>,
    duration: Option<RawSpan>,
    seed: Option<u64>,
    sample_every: Option<RawSpan>,
    #[serde(default)]
    nodes: Vec<RawNode>,
    #[serde(default)]
    faults: Vec<RawFault>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawNode {
    name: String,
    /// `controller` (the default), `slio` or `sja1000`.
    kind: Option<String>,
    /// An SJA1000's bus-off recovery: `counted` (the seed's, default) or `fast`.
    recovery: Option<String>,
    /// A SLIO's number, 0..F.
    id: Option<String>,
    /// A SLIO board's ADC1 and potentiometer voltages.
    adc1: Option<f64>,
    potentiometer: Option<f64>,
    #[serde(default)]
    listen_only: bool,
    #[serde(default)]
    self_test: bool,
    #[serde(default)]
    single_shot: bool,
    #[serde(default)]
    self_reception: bool,
    auto_recover: Option<bool>,
    tx_queue: Option<u64>,
    #[serde(default)]
    traffic: Vec<RawTraffic>,
}

#[derive(Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum RawTraffic {
    Periodic {
        frame: String,
        period: RawSpan,
        start: Option<RawSpan>,
        count: Option<u64>,
    },
    Burst {
        frame: String,
        count: u64,
        period: Option<RawSpan>,
        start: Option<RawSpan>,
    },
    File {
        id: String,
        size: Option<u64>,
        text: Option<String>,
        hex: Option<String>,
        start: Option<RawSpan>,
    },
    Once {
        frame: String,
        at: RawSpan,
    },
}

#[derive(Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum RawFault {
    Disconnect {
        node: String,
        start: RawSpan,
        end: Option<RawSpan>,
    },
    Cut {
        nodes: Vec<String>,
        error_rate: Option<f64>,
        start: RawSpan,
        end: Option<RawSpan>,
    },
    Flip {
        node: Option<String>,
        at: RawSpan,
        bits: Option<u64>,
    },
    StuckDominant {
        start: RawSpan,
        end: Option<RawSpan>,
    },
    Noise {
        nodes: Option<Vec<String>>,
        rate: f64,
        start: Option<RawSpan>,
        end: Option<RawSpan>,
    },
}

/// Resolves names and durations, with the context for error messages.
struct Resolver<'a> {
    bitrate: u32,
    names: &'a [String],
}

impl Resolver<'_> {
    fn span(&self, context: &str, raw: &RawSpan) -> Result<BitTime, ScenarioError> {
        Span::parse(&raw.0)
            .map(|s| s.to_bits(self.bitrate))
            .map_err(|error| ScenarioError::Duration {
                context: context.to_owned(),
                error,
            })
    }

    fn opt_span(
        &self,
        context: &str,
        raw: &Option<RawSpan>,
        default: BitTime,
    ) -> Result<BitTime, ScenarioError> {
        raw.as_ref().map_or(Ok(default), |r| self.span(context, r))
    }

    fn node(&self, context: &str, name: &str) -> Result<usize, ScenarioError> {
        self.names
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| ScenarioError::UnknownNode {
                context: context.to_owned(),
                name: name.to_owned(),
                known: self.names.join(", "),
            })
    }

    fn frame(&self, context: &str, text: &str) -> Result<Frame, ScenarioError> {
        text.parse().map_err(|error| ScenarioError::Frame {
            context: context.to_owned(),
            text: text.to_owned(),
            error,
        })
    }

    fn rate(&self, context: &str, what: &'static str, rate: f64) -> Result<f64, ScenarioError> {
        if (0.0..=1.0).contains(&rate) {
            Ok(rate)
        } else {
            Err(ScenarioError::OutOfRange {
                context: context.to_owned(),
                what,
                value: rate.to_string(),
                range: "0.0..=1.0",
            })
        }
    }

    fn window(
        &self,
        context: &str,
        start: &Option<RawSpan>,
        end: &Option<RawSpan>,
    ) -> Result<(BitTime, BitTime), ScenarioError> {
        let s = self.opt_span(context, start, BitTime::ZERO)?;
        let e = self.opt_span(context, end, BitTime::MAX)?;
        if e < s {
            let show = |r: &Option<RawSpan>| r.as_ref().map_or("0".to_owned(), |r| r.0.clone());
            return Err(ScenarioError::EndBeforeStart {
                context: context.to_owned(),
                start: show(start),
                end: show(end),
            });
        }
        Ok((s, e))
    }
}

impl RawScenario {
    fn resolve(self) -> Result<Scenario, ScenarioError> {
        let bitrate = match self.bitrate {
            None => 500_000,
            Some(b @ 1..=1_000_000) => b as u32,
            Some(b) => {
                return Err(ScenarioError::OutOfRange {
                    context: "bitrate".to_owned(),
                    what: "bit rate",
                    value: b.to_string(),
                    range: "1..=1000000 bit/s",
                });
            }
        };
        if self.nodes.is_empty() {
            return Err(ScenarioError::NoNodes);
        }
        let names: Vec<String> = self.nodes.iter().map(|n| n.name.clone()).collect();
        for (i, name) in names.iter().enumerate() {
            let ok = (1..=32).contains(&name.len())
                && name
                    .bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b"_-.".contains(&b));
            if !ok {
                return Err(ScenarioError::BadNodeName { name: name.clone() });
            }
            if names[..i].contains(name) {
                return Err(ScenarioError::DuplicateNode { name: name.clone() });
            }
        }
        let r = Resolver {
            bitrate,
            names: &names,
        };
        let duration = r.opt_span(
            "duration",
            &self.duration,
            Nanos::from_secs(1).bit_times_at(bitrate),
        )?;
        if duration > max_duration(bitrate) {
            return Err(ScenarioError::OutOfRange {
                context: "duration".to_owned(),
                what: "duration",
                value: self
                    .duration
                    .as_ref()
                    .map(|d| d.0.clone())
                    .unwrap_or_default(),
                range: "up to 1 h of virtual time",
            });
        }
        let sample_every = match &self.sample_every {
            Some(raw) => match r.span("sample_every", raw)? {
                BitTime::ZERO => {
                    return Err(ScenarioError::OutOfRange {
                        context: "sample_every".to_owned(),
                        what: "interval",
                        value: raw.0.clone(),
                        range: "at least 1 bit-time",
                    });
                }
                n => Some(n),
            },
            None => None,
        };
        let nodes = self
            .nodes
            .into_iter()
            .map(|n| n.resolve(&r))
            .collect::<Result<_, _>>()?;
        let faults = self
            .faults
            .into_iter()
            .enumerate()
            .map(|(i, f)| f.resolve(&r, &format!("fault {}", i + 1)))
            .collect::<Result<_, _>>()?;
        Ok(Scenario {
            bitrate,
            duration,
            seed: self.seed.unwrap_or(0),
            sample_every,
            nodes,
            faults,
        })
    }
}

impl RawNode {
    fn resolve(self, r: &Resolver) -> Result<NodeSpec, ScenarioError> {
        let defaults = ControllerConfig::default();
        let context = format!("node {:?}", self.name);
        let tx_queue_capacity = match self.tx_queue {
            None => defaults.tx_queue_capacity,
            Some(n @ 1..=4096) => n as usize,
            Some(n) => {
                return Err(ScenarioError::OutOfRange {
                    context,
                    what: "tx_queue",
                    value: n.to_string(),
                    range: "1..=4096",
                });
            }
        };
        let config = ControllerConfig {
            listen_only: self.listen_only,
            self_test: self.self_test,
            single_shot: self.single_shot,
            self_reception: self.self_reception,
            auto_recover: self.auto_recover.unwrap_or(defaults.auto_recover),
            tx_queue_capacity,
        };
        let traffic: Vec<Traffic> = self
            .traffic
            .into_iter()
            .enumerate()
            .map(|(i, t)| t.resolve(r, &format!("{context}, traffic {}", i + 1)))
            .collect::<Result<_, _>>()?;
        if self.recovery.is_some() && self.kind.as_deref() != Some("sja1000") {
            return Err(ScenarioError::OutOfRange {
                context,
                what: "recovery",
                value: format!("{:?}", self.recovery.unwrap_or_default()),
                range: "only for kind = \"sja1000\"",
            });
        }
        let kind = match self.kind.as_deref() {
            Some("sja1000") => {
                let fast_restart = match self.recovery.as_deref() {
                    None | Some("counted") => false,
                    Some("fast") => true,
                    Some(other) => {
                        return Err(ScenarioError::OutOfRange {
                            context,
                            what: "recovery",
                            value: format!("{other:?}"),
                            range: "\"counted\" (the seed's) or \"fast\"",
                        });
                    }
                };
                let controller_only = self.listen_only
                    || self.self_test
                    || self.single_shot
                    || self.self_reception
                    || self.auto_recover.is_some()
                    || self.tx_queue.is_some()
                    || self.id.is_some()
                    || self.adc1.is_some()
                    || self.potentiometer.is_some();
                if controller_only {
                    return Err(ScenarioError::OutOfRange {
                        context,
                        what: "option",
                        value: "of another kind".into(),
                        range: "an sja1000 node takes recovery and traffic only",
                    });
                }
                NodeKind::Sja1000(Sja1000Spec { fast_restart })
            }
            None | Some("controller") => {
                if let Some(id) = &self.id {
                    return Err(ScenarioError::OutOfRange {
                        context,
                        what: "id",
                        value: id.clone(),
                        range: "only for kind = \"slio\"",
                    });
                }
                NodeKind::Controller(config)
            }
            Some("slio") => {
                let id_text = self.id.as_deref().unwrap_or("");
                let id = id_text
                    .parse::<SlioId>()
                    .map_err(|_| ScenarioError::OutOfRange {
                        context: context.clone(),
                        what: "SLIO id",
                        value: format!("{id_text:?}"),
                        range: "0..F (one hex digit)",
                    })?;
                if !(buslab_slio::slio::MIN_BITRATE..=buslab_slio::slio::MAX_BITRATE)
                    .contains(&r.bitrate)
                {
                    return Err(ScenarioError::OutOfRange {
                        context,
                        what: "bit rate for a SLIO",
                        value: r.bitrate.to_string(),
                        range: "20000..=125000 bit/s (the P82C150's RC oscillator)",
                    });
                }
                if !traffic.is_empty() {
                    return Err(ScenarioError::OutOfRange {
                        context,
                        what: "traffic",
                        value: traffic.len().to_string(),
                        range: "none: a SLIO sends only its answers, sign-on and input reports",
                    });
                }
                let volts = |what: &'static str, v: Option<f64>, default: f64| match v {
                    None => Ok(default),
                    Some(v) if (0.0..=5.0).contains(&v) => Ok(v),
                    Some(v) => Err(ScenarioError::OutOfRange {
                        context: context.clone(),
                        what,
                        value: v.to_string(),
                        range: "0.0..=5.0 V",
                    }),
                };
                NodeKind::Slio {
                    id,
                    adc1: volts("adc1", self.adc1, 1.25)?,
                    potentiometer: volts("potentiometer", self.potentiometer, 2.5)?,
                }
            }
            Some(other) => {
                return Err(ScenarioError::OutOfRange {
                    context,
                    what: "kind",
                    value: format!("{other:?}"),
                    range: "\"controller\", \"slio\" or \"sja1000\"",
                });
            }
        };
        Ok(NodeSpec {
            name: self.name,
            kind,
            traffic,
        })
    }
}

impl RawTraffic {
    fn resolve(self, r: &Resolver, context: &str) -> Result<Traffic, ScenarioError> {
        Ok(match self {
            RawTraffic::Periodic {
                frame,
                period,
                start,
                count,
            } => {
                let period_bits = r.span(context, &period)?;
                if period_bits == BitTime::ZERO {
                    return Err(ScenarioError::OutOfRange {
                        context: context.to_owned(),
                        what: "period",
                        value: period.0,
                        range: "at least 1 bit-time",
                    });
                }
                // `count = 0` sent one frame: a count says how many, at least one.
                if count == Some(0) {
                    return Err(ScenarioError::OutOfRange {
                        context: context.to_owned(),
                        what: "count",
                        value: "0".into(),
                        range: "1 or more (leave it out for no end)",
                    });
                }
                Traffic::Periodic {
                    frame: r.frame(context, &frame)?,
                    period: period_bits,
                    start: r.opt_span(context, &start, BitTime::ZERO)?,
                    count,
                }
            }
            RawTraffic::Burst {
                frame,
                count,
                period,
                start,
            } => {
                if !(1..=4096).contains(&count) {
                    return Err(ScenarioError::OutOfRange {
                        context: context.to_owned(),
                        what: "burst count",
                        value: count.to_string(),
                        range: "1..=4096",
                    });
                }
                Traffic::Burst {
                    frame: r.frame(context, &frame)?,
                    count: count as u32,
                    period: r.opt_span(context, &period, BitTime::ZERO)?,
                    start: r.opt_span(context, &start, BitTime::ZERO)?,
                }
            }
            RawTraffic::File {
                id,
                size,
                text,
                hex,
                start,
            } => {
                let id_value: Id = id.parse().map_err(|error| ScenarioError::Id {
                    context: context.to_owned(),
                    text: id.clone(),
                    error,
                })?;
                let data = match (size, text, hex) {
                    (Some(n), None, None) if n as usize <= MAX_FILE => {
                        // A recognisable pattern that differs from chunk to chunk.
                        (0..n as usize).map(|i| (i % 251) as u8).collect()
                    }
                    (Some(n), None, None) => {
                        return Err(ScenarioError::OutOfRange {
                            context: context.to_owned(),
                            what: "file size",
                            value: n.to_string(),
                            range: "0..=16777216 bytes",
                        });
                    }
                    (None, Some(t), None) => t.into_bytes(),
                    (None, None, Some(h)) => parse_hex(&h).ok_or(ScenarioError::FileData {
                        context: context.to_owned(),
                        text: h,
                        why: "expected pairs of hex digits",
                    })?,
                    _ => {
                        return Err(ScenarioError::FileData {
                            context: context.to_owned(),
                            text: String::new(),
                            why: "give exactly one of size, text or hex",
                        });
                    }
                };
                Traffic::File {
                    id: id_value,
                    data,
                    start: r.opt_span(context, &start, BitTime::ZERO)?,
                }
            }
            RawTraffic::Once { frame, at } => Traffic::Once {
                frame: r.frame(context, &frame)?,
                at: r.span(context, &at)?,
            },
        })
    }
}

impl RawFault {
    fn resolve(self, r: &Resolver, context: &str) -> Result<Fault, ScenarioError> {
        let context = format!("{context} ({})", self.name());
        let context = context.as_str();
        let nodes = |list: &[String]| {
            list.iter()
                .map(|n| r.node(context, n))
                .collect::<Result<Vec<_>, _>>()
        };
        let (kind, (start, end)) = match self {
            RawFault::Disconnect { node, start, end } => (
                FaultKind::Disconnect {
                    node: r.node(context, &node)?,
                },
                r.window(context, &Some(start), &end)?,
            ),
            RawFault::Cut {
                nodes: far,
                error_rate,
                start,
                end,
            } => (
                FaultKind::Cut {
                    far_side: nodes(&far)?,
                    error_rate: r.rate(context, "error_rate", error_rate.unwrap_or(0.05))?,
                },
                r.window(context, &Some(start), &end)?,
            ),
            RawFault::Flip { node, at, bits } => {
                let node = node.map(|n| r.node(context, &n)).transpose()?;
                let at = r.span(context, &at)?;
                (
                    FaultKind::Flip { node },
                    (at, at.saturating_add(BitTime::new(bits.unwrap_or(1)))),
                )
            }
            RawFault::StuckDominant { start, end } => (
                FaultKind::StuckDominant,
                r.window(context, &Some(start), &end)?,
            ),
            RawFault::Noise {
                nodes: list,
                rate,
                start,
                end,
            } => (
                FaultKind::Noise {
                    nodes: nodes(list.as_deref().unwrap_or_default())?,
                    rate: r.rate(context, "rate", rate)?,
                },
                r.window(context, &start, &end)?,
            ),
        };
        Ok(Fault { kind, start, end })
    }

    fn name(&self) -> &'static str {
        match self {
            RawFault::Disconnect { .. } => "disconnect",
            RawFault::Cut { .. } => "cut",
            RawFault::Flip { .. } => "flip",
            RawFault::StuckDominant { .. } => "stuck_dominant",
            RawFault::Noise { .. } => "noise",
        }
    }
}

fn parse_hex(text: &str) -> Option<Vec<u8>> {
    let digits: Vec<u8> = text.bytes().filter(|b| !b.is_ascii_whitespace()).collect();
    // Hex digits only: `from_str_radix` would take a sign (`+f`).
    if !digits.len().is_multiple_of(2) || !digits.iter().all(u8::is_ascii_hexdigit) {
        return None;
    }
    digits
        .chunks(2)
        .map(|pair| u8::from_str_radix(core::str::from_utf8(pair).ok()?, 16).ok())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
        bitrate = 125000
        duration = "100ms"
        seed = 7
        sample_every = "1ms"

        [[nodes]]
        name = "a"
        [[nodes.traffic]]
        kind = "periodic"
        frame = "123#1122"
        period = "10ms"
        [[nodes.traffic]]
        kind = "file"
        id = "100"
        text = "hello, world"
        start = "100bits"

        [[nodes]]
        name = "b"
        listen_only = true

        [[faults]]
        kind = "cut"
        nodes = ["a"]
        start = "20ms"
        end = "30ms"

        [[faults]]
        kind = "flip"
        node = "b"
        at = "5000bits"
    "#;

    #[test]
    fn parses_a_full_scenario() {
        let s = Scenario::from_toml(GOOD).unwrap();
        assert_eq!(s.bitrate, 125_000);
        assert_eq!(s.duration, BitTime::new(12_500));
        assert_eq!(s.sample_every, Some(BitTime::new(125)));
        assert_eq!(s.nodes.len(), 2);
        assert!(matches!(s.nodes[1].kind, NodeKind::Controller(c) if c.listen_only));
        assert_eq!(
            s.nodes[0].traffic[0],
            Traffic::Periodic {
                frame: "123#1122".parse().unwrap(),
                period: BitTime::new(1250),
                start: BitTime::ZERO,
                count: None
            }
        );
        assert_eq!(s.faults[0].start, BitTime::new(2500));
        assert_eq!(s.faults[0].end, BitTime::new(3750));
        assert_eq!(
            s.faults[1],
            Fault {
                kind: FaultKind::Flip { node: Some(1) },
                start: BitTime::new(5000),
                end: BitTime::new(5001)
            }
        );
        assert_eq!(s.build().unwrap().nodes().len(), 2);
    }

    fn err(text: &str) -> String {
        Scenario::from_toml(text).unwrap_err().to_string()
    }

    const NODE: &str = "[[nodes]]\nname = \"a\"\n";

    #[test]
    fn bad_scenarios_name_the_value() {
        let cases: &[(String, &str)] = &[
            (
                format!("{NODE}[[faults]]\nkind = \"disconnect\"\nnode = \"zz\"\nstart = 0"),
                "unknown node \"zz\" (nodes are: a)",
            ),
            (
                format!("{NODE}[[nodes.traffic]]\nkind = \"once\"\nframe = \"123#R9\"\nat = 0"),
                "DLC 9 is out of range 0..8",
            ),
            (
                format!("{NODE}[[nodes.traffic]]\nkind = \"once\"\nframe = \"12#00\"\nat = 0"),
                "bad frame \"12#00\"",
            ),
            (
                format!(
                    "{NODE}[[nodes.traffic]]\nkind = \"periodic\"\nframe = \"123#\"\nperiod = \"1ms\"\ncount = 0"
                ),
                "count 0 is out of range 1 or more",
            ),
            (
                format!("{NODE}[[nodes.traffic]]\nkind = \"burst\"\nframe = \"123#+f\"\ncount = 1"),
                "bad frame \"123#+f\"",
            ),
            (
                format!("{NODE}kind = \"sja1000\"\nrecovery = \"slow\""),
                "recovery \"slow\" is out of range \"counted\"",
            ),
            (
                format!("{NODE}recovery = \"fast\""),
                "only for kind = \"sja1000\"",
            ),
            (
                format!(
                    "{NODE}[[nodes.traffic]]\nkind = \"once\"\nframe = \"123#010203040506070809\"\nat = 0"
                ),
                "9 data bytes",
            ),
            (
                format!(
                    "{NODE}[[faults]]\nkind = \"stuck_dominant\"\nstart = \"20ms\"\nend = \"10ms\""
                ),
                "fault 1 (stuck_dominant): end 10ms is before start 20ms",
            ),
            (
                format!("{NODE}[[faults]]\nkind = \"noise\"\nrate = 1.5"),
                "rate 1.5 is out of range 0.0..=1.0",
            ),
            (
                format!("duration = \"10 parsecs\"\n{NODE}"),
                "bad duration \"10 parsecs\"",
            ),
            (format!("bitrate = 2000000\n{NODE}"), "2000000"),
            (format!("{NODE}{NODE}"), "\"a\" is used twice"),
            ("[[nodes]]\nname = \"a b\"".to_owned(), "not allowed"),
            (String::new(), "no nodes"),
            (format!("{NODE}colour = 3"), "unknown field"),
            (
                format!("{NODE}[[nodes.traffic]]\nkind = \"teleport\""),
                "teleport",
            ),
            (
                format!("{NODE}[[nodes.traffic]]\nkind = \"file\"\nid = \"100\"\nhex = \"0g\""),
                "\"0g\"",
            ),
            (
                format!(
                    "{NODE}[[nodes.traffic]]\nkind = \"periodic\"\nframe = \"123#\"\nperiod = 0"
                ),
                "period 0 is out of range",
            ),
            ("this is [not toml".to_owned(), "not valid TOML"),
        ];
        for (text, needle) in cases {
            let e = err(text);
            assert!(
                e.contains(needle),
                "{text:?}\n -> {e}\n does not contain {needle:?}"
            );
        }
    }
}
