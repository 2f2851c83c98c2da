//! Errors of scenario files.

use buslab_sim::DurationError;

/// Something wrong with a simulation set-up or a scenario file.
///
/// The messages include the underlying error's text (and do not chain it as a `source`, so it
/// is not printed twice).
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("scenario is not valid TOML: {0}")]
    Toml(toml::de::Error),
    #[error("{context}: {error}")]
    Duration {
        context: String,
        error: DurationError,
    },
    #[error("{context}: bad frame {text:?}: {error}")]
    Frame {
        context: String,
        text: String,
        error: buslab_can::ParseError,
    },
    #[error("{context}: bad identifier {text:?}: {error}")]
    Id {
        context: String,
        text: String,
        error: buslab_can::ParseError,
    },
    #[error("{context}: unknown node {name:?} (nodes are: {known})")]
    UnknownNode {
        context: String,
        name: String,
        known: String,
    },
    #[error("node name {name:?} is used twice")]
    DuplicateNode { name: String },
    #[error("node name {name:?} is not allowed: use 1..32 characters from A-Z a-z 0-9 _ - .")]
    BadNodeName { name: String },
    #[error("{context}: end {end} is before start {start}")]
    EndBeforeStart {
        context: String,
        start: String,
        end: String,
    },
    #[error("{context}: {what} {value} is out of range {range}")]
    OutOfRange {
        context: String,
        what: &'static str,
        value: String,
        range: &'static str,
    },
    #[error("{context}: file data {text:?} is not valid: {why}")]
    FileData {
        context: String,
        text: String,
        why: &'static str,
    },
    #[error("scenario has no nodes; add at least one [[nodes]] table")]
    NoNodes,
    /// The node factory could not make the node (an SJA1000 at this bit rate).
    #[error("node {node:?}: {why}")]
    Node { node: String, why: String },
}

impl From<toml::de::Error> for ScenarioError {
    fn from(error: toml::de::Error) -> Self {
        ScenarioError::Toml(error)
    }
}
