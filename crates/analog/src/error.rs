//! Why a source was refused.

/// Why a source spec or replay file was refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SourceError {
    #[error("analog source `{spec}`: {why}")]
    Spec { spec: String, why: String },
    #[error("analog input `{arg}`: channel `{channel}` is out of range {first}..{last}")]
    Channel {
        arg: String,
        channel: String,
        first: u8,
        last: u8,
    },
    #[error("replay CSV line {line} `{text}`: {why}")]
    CsvLine {
        line: usize,
        text: String,
        why: String,
    },
    #[error("replay CSV has no `seconds,volts` rows")]
    CsvEmpty,
}
