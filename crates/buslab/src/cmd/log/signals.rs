//! `log convert IN OUT.csv --dbc FILE`: the decoded signals as a table, one row per data
//! frame of a message of the database, one column per signal (`Message.Signal`), written
//! through the [`LogWriter`] seam so that `convert` treats it as any output (atomic, or in
//! place with `--follow`).
//!
//! ```text
//! time,id,message,Engine.Speed,Engine.Mode,Brake.Pressure
//! 1700000000.000100,0x123,Engine,100.0,1,
//! 1700000000.000350,0x124,Brake,,,12.5
//! ```

use std::collections::HashMap;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;
use std::sync::Arc;

use buslab_can::Id;
use buslab_dbc::text::Number;
use buslab_dbc::{Database, Decoded};
use buslab_link::fs::Staged;
use buslab_logs::{LogWriter, Message, text};

use crate::dbc::{MessageFilter, carried};

/// The first columns, before the signals.
const FIXED: &str = "time,id,message";

/// Where the table goes: a temporary file put in place at the end, or the file itself
/// (`--follow`, flushed as the input grows).
enum Output {
    Atomic(BufWriter<Staged>),
    Direct(BufWriter<File>),
}

impl Output {
    fn writer(&mut self) -> &mut dyn Write {
        match self {
            Output::Atomic(w) => w,
            Output::Direct(w) => w,
        }
    }
}

/// The decoded-signal table as a log writer.
pub struct SignalCsv {
    out: Output,
    database: Arc<Database>,
    /// Each kept message's first column (after [`FIXED`]), by ID.
    first_column: HashMap<Id, usize>,
    columns: usize,
    values: Vec<Decoded>,
    line: Vec<u8>,
    left_out: u64,
}

impl SignalCsv {
    /// Creates the table at `path` (atomically unless `in_place`), its header written: the
    /// signals of every message of `database`, or of the messages `filter` keeps.
    pub fn create(
        path: &Path,
        database: Arc<Database>,
        filter: Option<&MessageFilter>,
        in_place: bool,
    ) -> anyhow::Result<Self> {
        let out = if in_place {
            let file = buslab_link::fs::open_regular(path, true).map_err(|source| {
                buslab_link::fs::WriteError {
                    path: path.to_path_buf(),
                    source,
                }
            })?;
            Output::Direct(BufWriter::with_capacity(BUFFER, file))
        } else {
            Output::Atomic(BufWriter::with_capacity(BUFFER, Staged::create(path)?))
        };
        let mut header = FIXED.to_string();
        let mut first_column = HashMap::new();
        let mut columns = 0;
        for message in database.messages() {
            if filter.is_some_and(|f| !f.passes_id(message.id())) {
                continue;
            }
            first_column.insert(message.id(), columns);
            for signal in message.signals() {
                header.push(',');
                header.push_str(message.name());
                header.push('.');
                header.push_str(signal.name());
                columns += 1;
            }
        }
        header.push('\n');
        let mut table = Self {
            out,
            database,
            first_column,
            columns,
            values: Vec::new(),
            line: Vec::with_capacity(256),
            left_out: 0,
        };
        // An empty log still gives a table with its header.
        table.out.writer().write_all(header.as_bytes())?;
        table.out.writer().flush()?;
        Ok(table)
    }
}

/// The output buffer.
const BUFFER: usize = 256 * 1024;

impl LogWriter for SignalCsv {
    fn write(&mut self, entry: &Message) -> io::Result<()> {
        let Some((id, payload)) = carried(&entry.record) else {
            self.left_out += 1;
            return Ok(());
        };
        let (Some(&first), Some(message)) = (self.first_column.get(&id), self.database.message(id))
        else {
            self.left_out += 1;
            return Ok(());
        };
        message.decode_into(payload, &mut self.values);
        let line = &mut self.line;
        line.clear();
        push_seconds(line, entry.at.since_epoch_duration());
        line.extend_from_slice(b",0x");
        push_id(line, id);
        line.push(b',');
        line.extend_from_slice(message.name().as_bytes());
        line.resize(line.len() + first, b',');
        // `values` is in signal order, each signal at most once.
        let mut decoded = self.values.iter().peekable();
        for (index, signal) in message.signals().iter().enumerate() {
            line.push(b',');
            if let Some(value) = decoded.next_if(|d| d.signal == index) {
                // Writing into a Vec cannot fail.
                let _ = write!(line, "{}", Number::of(signal, value.physical));
            }
        }
        let after = self.columns - first - message.signals().len();
        line.resize(line.len() + after, b',');
        line.push(b'\n');
        self.out.writer().write_all(line)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.out.writer().flush()
    }

    fn finish(self: Box<Self>) -> io::Result<()> {
        match self.out {
            Output::Atomic(w) => {
                let staged = w.into_inner().map_err(io::IntoInnerError::into_error)?;
                staged
                    .commit()
                    .map_err(|e| io::Error::new(e.source.kind(), e))
            }
            Output::Direct(w) => {
                let file = w.into_inner().map_err(io::IntoInnerError::into_error)?;
                file.sync_all()
            }
        }
    }

    /// Error frames, remote frames and frames of messages not kept.
    fn left_out(&self) -> u64 {
        self.left_out
    }
}

/// Seconds with six decimals, nine when the time has nanoseconds: exact, and a number to any
/// reader of CSV.
fn push_seconds(out: &mut Vec<u8>, t: std::time::Duration) {
    text::push_u64(out, t.as_secs());
    out.push(b'.');
    let nanos = t.subsec_nanos();
    if nanos.is_multiple_of(1000) {
        text::push_u64_zeros(out, u64::from(nanos / 1000), 6);
    } else {
        text::push_u64_zeros(out, u64::from(nanos), 9);
    }
}

/// The ID's can-utils digits (3 for a standard ID, 8 for an extended one) after `0x`, so that
/// no spreadsheet reads `1E5` as a number.
fn push_id(out: &mut Vec<u8>, id: Id) {
    let width = if id.is_extended() { 8 } else { 3 };
    text::push_hex(out, id.as_raw(), width);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_keep_their_precision_and_ids_their_width() {
        let mut out = Vec::new();
        push_seconds(&mut out, std::time::Duration::new(1_700_000_000, 100_000));
        out.push(b' ');
        push_seconds(&mut out, std::time::Duration::new(3, 5));
        out.push(b' ');
        push_id(&mut out, Id::standard(0x1E5).unwrap());
        out.push(b' ');
        push_id(&mut out, Id::extended(0x123).unwrap());
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "1700000000.000100 3.000000005 1E5 00000123"
        );
    }
}
