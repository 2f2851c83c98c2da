//! What the loader shows on the node's terminal when a transfer ends: the loaded ranges and the
//! entry point, or every bad line with its number. Lines of at most 80 columns.

use crate::loader::{IDLE_TIMEOUT, Outcome};
use crate::memory::TEXT_BUFFER;

/// Ranges listed at most; beyond, they are counted.
pub const MAX_RANGES: usize = 10;
/// Bad lines listed at most; beyond, they are counted.
pub const MAX_ERROR_LINES: usize = 12;
const COLS: usize = 80;

fn fit(mut line: String) -> String {
    if line.len() > COLS {
        let mut cut = COLS - 1;
        while !line.is_char_boundary(cut) {
            cut -= 1;
        }
        line.truncate(cut);
        line.push('~');
    }
    line
}

/// `00030000-0003003F      64 bytes`.
pub fn range_line(start: u32, end: u32) -> String {
    let len = u64::from(end) - u64::from(start) + 1;
    format!("{start:08X}-{end:08X} {len:>9} bytes")
}

/// The report of `outcome`, one line per row.
pub fn report(outcome: &Outcome) -> Vec<String> {
    let mut lines = Vec::new();
    match outcome {
        Outcome::Loaded {
            program,
            text_bytes,
        } => {
            let header = program
                .header_text()
                .map(|h| format!(", header \"{}\"", h.trim_end_matches(['\0', ' '])))
                .unwrap_or_default();
            lines.push(format!("Program loaded: {} bytes", program.data_bytes()));
            lines.push(format!(
                "From {text_bytes} bytes of S-records, {} records{header}",
                program.records
            ));
            let ranges = program.ranges();
            lines.push(format!("Loaded ranges ({}):", ranges.len()));
            for &(start, end) in ranges.iter().take(MAX_RANGES) {
                lines.push(format!("  {}", range_line(start, end)));
            }
            if ranges.len() > MAX_RANGES {
                lines.push(format!("  ... and {} more ranges", ranges.len() - MAX_RANGES));
            }
            lines.push(match program.start {
                Some(entry) => format!("Entry point: {entry:08X}"),
                None => "Entry point: none (the file has no S7/S8/S9 record)".to_string(),
            });
        }
        Outcome::Refused { errors, .. } => {
            lines.push(format!(
                "File refused: {} bad record(s); nothing was loaded",
                errors.count()
            ));
            for e in errors.errors.iter().take(MAX_ERROR_LINES) {
                lines.push(format!("  {e}"));
            }
            let more = errors.count().saturating_sub(MAX_ERROR_LINES);
            if more > 0 {
                lines.push(format!("  ... and {more} more bad records"));
            }
        }
        Outcome::TooLong { text_bytes } => lines.push(format!(
            "File refused: {text_bytes} bytes, longer than the loader's buffer ({TEXT_BUFFER} bytes); nothing was loaded"
        )),
        Outcome::Stopped { text_bytes } => lines.push(format!(
            "Transfer stopped: no frame for {} s after {text_bytes} bytes; nothing was loaded",
            IDLE_TIMEOUT.as_duration().as_secs()
        )),
    }
    lines.into_iter().map(fit).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::srec;

    #[test]
    fn the_report_lists_ranges_and_bad_lines() {
        let text = srec::write(
            b"prog",
            [(0x30000, &[0u8; 64][..]), (0x32000, &[1u8; 256][..])],
            Some(0x32000),
        );
        let program = srec::parse(&text).unwrap();
        let lines = report(&Outcome::Loaded {
            program,
            text_bytes: text.len(),
        });
        assert_eq!(lines[0], "Program loaded: 320 bytes");
        assert!(
            lines[1].ends_with(", 13 records, header \"prog\""),
            "{}",
            lines[1]
        );
        assert_eq!(lines[2], "Loaded ranges (2):");
        assert_eq!(lines[3], "  00030000-0003003F        64 bytes");
        assert_eq!(lines[4], "  00032000-000320FF       256 bytes");
        assert_eq!(lines[5], "Entry point: 00032000");
        let bad = b"S1030000FD\nS9030000FC\n";
        let errors = srec::parse(bad).unwrap_err();
        let lines = report(&Outcome::Refused {
            errors,
            text_bytes: bad.len(),
        });
        assert_eq!(
            lines[0],
            "File refused: 1 bad record(s); nothing was loaded"
        );
        assert!(lines[1].starts_with("  line 1: checksum"));
        assert!(lines.iter().all(|l| l.len() <= 80));
    }
}
