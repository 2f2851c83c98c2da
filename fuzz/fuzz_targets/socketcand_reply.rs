//! buslab's extension replies as the client reads them (`parse_status`, `parse_regs`,
//! `parse_nodes`, `parse_flushed`, `parse_refused`, `parse_board` over a reply's tokens): no panic, and what
//! was accepted prints as fields that read back to the same value.
#![no_main]

use buslab_fuzz::text;
use buslab_socketcand::reply::{
    board_fields, flushed_fields, nodes_fields, parse_board, parse_flushed, parse_nodes,
    parse_refused, parse_regs, parse_status, refused_fields, regs_fields, status_fields,
};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some(text) = text(data) else { return };
    let tokens: Vec<&str> = text.split_ascii_whitespace().collect();
    if let Ok(status) = parse_status(&tokens) {
        // Fields print with fixed precision (bus load to 0.1 %): one round trip settles them.
        let fields = status_fields(&status);
        let again = parse_status(&fields).expect("printed status parses");
        assert_eq!(status_fields(&again), fields);
    }
    if let Ok(regs) = parse_regs(&tokens) {
        let fields = regs_fields(&regs);
        assert_eq!(parse_regs(&fields).expect("printed regs parse"), regs);
    }
    if let Ok(nodes) = parse_nodes(&tokens) {
        let fields = nodes_fields(&nodes);
        assert_eq!(parse_nodes(&fields).expect("printed nodes parse"), nodes);
    }
    if let Ok(limit) = parse_refused(&tokens) {
        let fields = refused_fields(&limit);
        assert_eq!(
            parse_refused(&fields).expect("printed refusal parses"),
            limit
        );
    }
    if let Ok(report) = parse_flushed(&tokens) {
        let fields = flushed_fields(&report);
        assert_eq!(
            parse_flushed(&fields).expect("printed report parses"),
            report
        );
    }
    if let Ok(board) = parse_board(&tokens) {
        let fields = board_fields(&board);
        assert_eq!(parse_board(&fields).expect("printed board parses"), board);
    }
});
