//! Where everything is on MoniCAN's screen (the seed's Fig. 4.2), 1-based rows and columns of
//! a 24 × 80 VT100:
//!
//! ```text
//!  1 *** MoniCAN (C) ESIEE 1999 ***
//!  2 SLIO | DIGITAL OUTPUTS | DIGITAL INPUTS | ADC1 | ADC2 | DPM1 | DPM2
//!  3      0 | XXXX            | XXXX           | XX   | XX   | XX   | XX
//!    ...  (one row per SLIO 0..F; a `*` in column 1 marks a SLIO that signed on)
//! 18      F | XXXX            | XXXX           | XX   | XX   | XX   | XX
//! 19 Last frame received : ID1:53 ID2:A0 DATA1:23 DATA2:20 DATA3:00
//! 20 (notices: you've got mail ! (press Ctrl R to read it), the loader, no answer)
//! 21 -------------------------------------------------------------------
//! 22 ID_slio:3 Data input:2001
//! 23 ID_slio:3 Data_output:2000
//! 24 Next command > SLIO:_ I/O:_ PIN:_ VALUE:__
//! ```
//!
//! The header is the seed's, word for word; the SLIO rows are aligned under it (the figure's
//! rows, as printed, are not: docs/decisions.md).

use buslab_slio::SlioId;

pub const TITLE: &str = "*** MoniCAN (C) ESIEE 1999 ***";
pub const HEADER: &str = "SLIO | DIGITAL OUTPUTS | DIGITAL INPUTS | ADC1 | ADC2 | DPM1 | DPM2";

pub const TITLE_ROW: u8 = 1;
pub const HEADER_ROW: u8 = 2;
/// The row of SLIO 0; SLIO n is on `FIRST_SLIO_ROW + n`.
pub const FIRST_SLIO_ROW: u8 = 3;
pub const LAST_FRAME_ROW: u8 = 19;
pub const NOTICE_ROW: u8 = 20;
pub const RULE_ROW: u8 = 21;
/// The last answer to an input command (DATA_INPUT, ADC).
pub const INPUT_LOG_ROW: u8 = 22;
/// The last answer to an output command (DATA_OUTPUT, DPM, the other registers).
pub const OUTPUT_LOG_ROW: u8 = 23;
pub const COMMAND_ROW: u8 = 24;

/// The `*` of a SLIO that signed on.
pub const MARK_COL: u8 = 1;
/// The SLIO's number, under the `O` of `SLIO`.
pub const SLIO_COL: u8 = 4;
/// The 4 hex digits of DATA_OUTPUT, under `DIGITAL OUTPUTS`.
pub const OUTPUTS_COL: u8 = 8;
/// The 4 hex digits of DATA_INPUT, under `DIGITAL INPUTS`.
pub const INPUTS_COL: u8 = 26;
/// Two hex digits each, under their titles.
pub const ADC1_COL: u8 = 43;
pub const ADC2_COL: u8 = 50;
pub const DPM1_COL: u8 = 57;
pub const DPM2_COL: u8 = 64;

/// The screen row of a SLIO.
pub fn slio_row(slio: SlioId) -> u8 {
    FIRST_SLIO_ROW + slio.number()
}

/// A SLIO's row with every value unknown (`XXXX`, `XX`), unmarked.
pub fn blank_row(slio: SlioId) -> String {
    format!(
        "   {slio} | {:<15} | {:<14} | {:<4} | {:<4} | {:<4} | {}",
        "XXXX", "XXXX", "XX", "XX", "XX", "XX"
    )
}

/// `-` under the whole table.
pub fn rule() -> String {
    "-".repeat(HEADER.len())
}

/// The command line's fixed text, and the column of each field's first character.
pub const COMMAND_PROMPT: &str = "Next command > ";
pub const SLIO_FIELD: (&str, u8) = ("SLIO:", 21);
pub const IO_FIELD: (&str, u8) = (" I/O:", 27);
pub const PIN_FIELD: (&str, u8) = (" PIN:", 33);
pub const VALUE_FIELD: (&str, u8) = (" VALUE:", 41);
/// Characters of the value field (two hex digits).
pub const VALUE_WIDTH: usize = 2;

/// The command line with no field typed: `Next command > SLIO:_ I/O:_ PIN:_ VALUE:__`.
pub fn blank_command_line() -> String {
    format!(
        "{COMMAND_PROMPT}{}_{}_{}_{}{}",
        SLIO_FIELD.0,
        IO_FIELD.0,
        PIN_FIELD.0,
        VALUE_FIELD.0,
        "_".repeat(VALUE_WIDTH)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_line_up_under_the_header() {
        let row = blank_row(SlioId::new(3).unwrap());
        let bars = |s: &str| s.match_indices('|').map(|(i, _)| i).collect::<Vec<_>>();
        assert_eq!(bars(&row), bars(HEADER));
        let col = |c: u8| row.as_bytes()[usize::from(c) - 1] as char;
        assert_eq!(col(SLIO_COL), '3');
        for c in [
            OUTPUTS_COL,
            INPUTS_COL,
            ADC1_COL,
            ADC2_COL,
            DPM1_COL,
            DPM2_COL,
        ] {
            assert_eq!(col(c), 'X', "column {c}");
            assert_eq!(row.as_bytes()[usize::from(c) - 3] as char, '|');
        }
        let find = |word: &str| HEADER.find(word).unwrap() as u8 + 1;
        assert_eq!(find("DIGITAL OUTPUTS"), OUTPUTS_COL);
        assert_eq!(find("DIGITAL INPUTS"), INPUTS_COL);
        assert_eq!(find("ADC1"), ADC1_COL);
        assert_eq!(find("ADC2"), ADC2_COL);
        assert_eq!(find("DPM1"), DPM1_COL);
        assert_eq!(find("DPM2"), DPM2_COL);
    }

    #[test]
    fn the_command_line_fields_are_where_the_columns_say() {
        let line = blank_command_line();
        assert_eq!(line, "Next command > SLIO:_ I/O:_ PIN:_ VALUE:__");
        for (label, col) in [SLIO_FIELD, IO_FIELD, PIN_FIELD, VALUE_FIELD] {
            let at = line.find(label).unwrap() + label.len() + 1;
            assert_eq!(at as u8, col, "{label}");
        }
    }
}
