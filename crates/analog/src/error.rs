//! Why a source was refused.

/// Why a source spec or replay file was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SourceError {
    #[error("analog source `{spec}`: {why}")]
    Spec { spec: String, why: String },
    #[error("replay CSV line {line} `{text}`: {why}")]
    CsvLine {
        line: usize,
        text: String,
        why: String,
    },
    #[error("replay CSV has no `seconds,volts` rows")]
    CsvEmpty,
}
