//! One look at a mailbox, `buslab_mail::imap::Poll`, against scripted server answers in
//! virtual time: what it sends, what it finds, and how it refuses a server that misbehaves.

use std::time::{Duration, Instant};

use buslab_mail::imap::{
    Event, FrameError, Limits, Outcome, Poll, PollConfig, PollError, Security, Step, Watermark,
    fetch_bytes,
};

const TIMEOUT: Duration = Duration::from_secs(30);

fn config(security: Security, known: Option<Watermark>) -> PollConfig {
    PollConfig {
        user: "alice".into(),
        password: "s3cret".into(),
        mailbox: "INBOX".into(),
        security,
        known,
        fetch_at_most: 16,
        text_limit: 2048,
        timeout: TIMEOUT,
        limits: Limits::DEFAULT,
        response_limit: 16 << 20,
    }
}

/// A poll and its clock.
struct Client {
    poll: Poll,
    now: Instant,
}

impl Client {
    fn new(config: PollConfig) -> Self {
        let now = Instant::now();
        Self {
            poll: Poll::new(config, now),
            now,
        }
    }

    /// The server says `reply`; returns what the client sent back.
    fn hear(&mut self, reply: &[u8]) -> Result<String, PollError> {
        self.poll.handle_input(reply, self.now)?;
        Ok(self.sent())
    }

    fn sent(&mut self) -> String {
        let mut sent = Vec::new();
        while let Some(bytes) = self.poll.poll_transmit() {
            sent.extend(bytes);
        }
        String::from_utf8(sent).unwrap()
    }

    fn event(&mut self) -> Option<Event> {
        self.poll.poll_event()
    }

    fn outcome(&mut self) -> Outcome {
        match self.event() {
            Some(Event::Done(outcome)) => outcome,
            other => panic!("no outcome: {other:?}"),
        }
    }
}

/// Logged in with `security` (Plain or Tls) and the mailbox examined (UIDVALIDITY 7, UIDNEXT
/// 10, 3 mails).
fn examined(known: Option<Watermark>) -> Client {
    let mut c = Client::new(config(Security::Plain, known));
    assert_eq!(
        c.hear(b"* OK [CAPABILITY IMAP4rev1 AUTH=PLAIN] ready\r\n")
            .unwrap(),
        "b1 LOGIN alice s3cret\r\n"
    );
    assert_eq!(
        c.hear(b"b1 OK [CAPABILITY IMAP4rev1] Logged in\r\n")
            .unwrap(),
        "b2 EXAMINE INBOX\r\n"
    );
    c
}

const EXAMINE_ANSWER: &[u8] = b"* FLAGS (\\Answered \\Flagged \\Deleted \\Seen \\Draft)\r\n\
* OK [PERMANENTFLAGS ()] Read-only mailbox.\r\n\
* 3 EXISTS\r\n* 0 RECENT\r\n\
* OK [UIDVALIDITY 7] UIDs valid\r\n* OK [UIDNEXT 10] Predicted next UID\r\n\
b2 OK [READ-ONLY] Examine completed (0.001 + 0.000 secs).\r\n";

#[test]
fn the_first_look_starts_tls_logs_in_and_sets_the_watermark_without_fetching() {
    let mut c = Client::new(config(Security::StartTls, None));
    assert_eq!(
        c.hear(b"* OK [CAPABILITY IMAP4rev1 SASL-IR STARTTLS AUTH=PLAIN] Dovecot ready.\r\n")
            .unwrap(),
        "b1 STARTTLS\r\n"
    );
    assert_eq!(c.hear(b"b1 OK Begin TLS negotiation now.\r\n").unwrap(), "");
    assert_eq!(c.event(), Some(Event::StartTls));
    assert_eq!(c.poll.step(), Step::Handshake);
    c.poll.tls_started(c.now).unwrap();
    assert_eq!(c.sent(), "b2 LOGIN alice s3cret\r\n");
    assert_eq!(
        c.hear(b"b2 OK Logged in\r\n").unwrap(),
        "b3 EXAMINE INBOX\r\n"
    );
    let answer = String::from_utf8(EXAMINE_ANSWER.to_vec())
        .unwrap()
        .replace("b2 OK", "b3 OK");
    assert_eq!(c.hear(answer.as_bytes()).unwrap(), "b4 LOGOUT\r\n");
    assert_eq!(
        c.outcome(),
        Outcome {
            watermark: Watermark {
                uid_validity: Some(7),
                last_uid: 9
            },
            existing: 3,
            mails: vec![],
            more: false,
            renumbered: false,
        }
    );
    assert_eq!(c.poll.deadline(), None, "nothing more is waited for");
}

#[test]
fn new_mails_are_searched_above_the_watermark_and_fetched_in_part() {
    let known = Watermark {
        uid_validity: Some(7),
        last_uid: 9,
    };
    let mut c = examined(Some(known));
    assert_eq!(
        c.hear(EXAMINE_ANSWER).unwrap(),
        "b3 UID SEARCH UID 10:*\r\n"
    );
    // `10:*` with nothing above 9 still matches the last mail (9): not new.
    let fetch = c
        .hear(b"* SEARCH 9 12 10\r\nb3 OK Search completed\r\n")
        .unwrap();
    assert_eq!(
        fetch,
        format!(
            "b4 UID FETCH 10,12 (UID RFC822.SIZE BODY.PEEK[]<0.{}>)\r\n",
            fetch_bytes(2048)
        )
    );
    let first = b"From: Alice <a@example.org>\r\nSubject: one\r\n\r\nfirst text\r\n";
    let mut answer = format!(
        "* 2 FETCH (UID 12 RFC822.SIZE 500000 BODY[]<0> {{{}}}\r\n",
        8
    )
    .into_bytes();
    answer.extend(b"From: b\r");
    answer.extend(b")\r\n");
    answer.extend(
        format!(
            "* 1 FETCH (UID 10 RFC822.SIZE {} BODY[]<0> {{{}}}\r\n",
            first.len(),
            first.len()
        )
        .as_bytes(),
    );
    answer.extend(first);
    answer.extend(b")\r\n* 1 FETCH (FLAGS (\\Seen))\r\nb4 OK Fetch completed\r\n");
    assert_eq!(c.hear(&answer).unwrap(), "b5 LOGOUT\r\n");
    let outcome = c.outcome();
    assert_eq!(outcome.watermark.last_uid, 12);
    assert_eq!(outcome.mails.len(), 2, "{outcome:?}");
    assert_eq!(
        String::from_utf8_lossy(&outcome.mails[0]),
        "From: Alice <a@example.org>\nSubject: one\n\nfirst text"
    );
    assert!(
        String::from_utf8_lossy(&outcome.mails[1]).ends_with("[... 499992 more bytes not sent]"),
        "{:?}",
        String::from_utf8_lossy(&outcome.mails[1])
    );
}

#[test]
fn at_most_the_oldest_new_mails_are_fetched_and_the_rest_wait() {
    let mut config = config(
        Security::Plain,
        Some(Watermark {
            uid_validity: Some(7),
            last_uid: 9,
        }),
    );
    config.fetch_at_most = 2;
    let mut c = Client::new(config);
    c.hear(b"* OK ready\r\n").unwrap();
    c.hear(b"b1 OK in\r\n").unwrap();
    c.hear(EXAMINE_ANSWER).unwrap();
    let fetch = c
        .hear(b"* SEARCH 15 11 13\r\n* SEARCH 14 10\r\nb3 OK\r\n")
        .unwrap();
    assert!(fetch.starts_with("b4 UID FETCH 10,11 "), "{fetch}");
    // The server lost them meanwhile (expunged): the watermark still passes them.
    c.hear(b"b4 OK Fetch completed\r\n").unwrap();
    let outcome = c.outcome();
    assert_eq!((outcome.watermark.last_uid, outcome.more), (11, true));
    assert!(outcome.mails.is_empty());
}

#[test]
fn a_changed_uidvalidity_starts_the_watermark_again() {
    let mut c = examined(Some(Watermark {
        uid_validity: Some(6),
        last_uid: 400,
    }));
    assert_eq!(c.hear(EXAMINE_ANSWER).unwrap(), "b3 LOGOUT\r\n");
    let outcome = c.outcome();
    assert!(outcome.renumbered);
    assert_eq!(
        outcome.watermark,
        Watermark {
            uid_validity: Some(7),
            last_uid: 9
        }
    );
}

#[test]
fn without_uidnext_the_last_mail_gives_the_watermark() {
    let mut c = examined(None);
    assert_eq!(
        c.hear(b"* 3 EXISTS\r\nb2 OK done\r\n").unwrap(),
        "b3 FETCH 3 (UID)\r\n"
    );
    c.hear(b"* 3 FETCH (UID 77)\r\nb3 OK done\r\n").unwrap();
    assert_eq!(c.outcome().watermark.last_uid, 77);
}

#[test]
fn no_login_is_sent_when_the_server_does_not_offer_starttls() {
    let mut c = Client::new(config(Security::StartTls, None));
    assert_eq!(c.hear(b"* OK ready\r\n").unwrap(), "b1 CAPABILITY\r\n");
    let refused = c.hear(b"* CAPABILITY IMAP4rev1 AUTH=PLAIN\r\nb1 OK done\r\n");
    assert_eq!(refused, Err(PollError::NoStartTls));
    assert_eq!(c.sent(), "", "no LOGIN, no password");
    // PREAUTH in clear text: nothing can be protected any more.
    let mut c = Client::new(config(Security::StartTls, None));
    assert_eq!(
        c.hear(b"* PREAUTH [CAPABILITY IMAP4rev1 STARTTLS] hi\r\n"),
        Err(PollError::PreauthInClear)
    );
}

#[test]
fn bytes_after_starttls_ok_are_refused_not_taken_as_protected() {
    let mut c = Client::new(config(Security::StartTls, None));
    c.hear(b"* OK [CAPABILITY IMAP4rev1 STARTTLS] ready\r\n")
        .unwrap();
    assert_eq!(
        c.hear(b"b1 OK go ahead\r\n* OK [CAPABILITY IMAP4rev1 AUTH=PLAIN] injected\r\n"),
        Err(PollError::StartTlsInjection)
    );
    let mut c = Client::new(config(Security::StartTls, None));
    c.hear(b"* OK [CAPABILITY IMAP4rev1 STARTTLS] ready\r\n")
        .unwrap();
    c.hear(b"b1 OK go ahead\r\n").unwrap();
    assert_eq!(c.hear(b"x"), Err(PollError::StartTlsInjection));
}

#[test]
fn an_answer_to_a_command_not_yet_sent_is_refused() {
    // Found by the fuzzer: the answer to CAPABILITY and an "OK" for STARTTLS in one read,
    // before STARTTLS was sent; taking it would start TLS on a reply made up in advance.
    let mut c = Client::new(config(Security::StartTls, None));
    assert_eq!(c.hear(b"* OK hi\r\n").unwrap(), "b1 CAPABILITY\r\n");
    assert_eq!(
        c.hear(b"* CAPABILITY IMAP4rev1 STARTTLS\r\nb1 OK\r\nb2 OK go\r\n"),
        Err(PollError::AnsweredBeforeAsked {
            step: Step::StartTls
        })
    );
    // The same with LOGIN's literal: "+" then OK before the password went out.
    let mut config = config(Security::Plain, None);
    config.password = "pässword".into();
    let mut c = Client::new(config);
    assert_eq!(c.hear(b"* OK ready\r\n").unwrap(), "b1 LOGIN alice {9}\r\n");
    assert_eq!(
        c.hear(b"+ go ahead\r\nb1 OK in\r\n"),
        Err(PollError::AnsweredBeforeAsked { step: Step::Login })
    );
}

#[test]
fn a_literal_password_waits_for_the_servers_go_ahead() {
    let mut config = config(Security::Plain, None);
    config.password = "pässword".into();
    let mut c = Client::new(config);
    assert_eq!(c.hear(b"* OK ready\r\n").unwrap(), "b1 LOGIN alice {9}\r\n");
    assert_eq!(c.hear(b"+ go ahead\r\n").unwrap(), "pässword\r\n");
    assert_eq!(c.hear(b"b1 OK in\r\n").unwrap(), "b2 EXAMINE INBOX\r\n");
}

#[test]
fn refusals_name_what_was_refused() {
    let mut c = Client::new(config(Security::Plain, None));
    c.hear(b"* OK ready\r\n").unwrap();
    assert_eq!(
        c.hear(b"b1 NO [AUTHENTICATIONFAILED] Authentication failed.\r\n"),
        Err(PollError::LoginRefused {
            user: "alice".into(),
            text: "Authentication failed.".into()
        })
    );
    let mut c = examined(None);
    assert_eq!(
        c.hear(b"b2 NO Mailbox doesn't exist: INBOX\r\n"),
        Err(PollError::MailboxRefused {
            mailbox: "INBOX".into(),
            text: "Mailbox doesn't exist: INBOX".into()
        })
    );
    let mut c = Client::new(config(Security::Plain, None));
    assert_eq!(
        c.hear(b"* BYE too many connections\r\n"),
        Err(PollError::Bye {
            step: Step::Greeting,
            text: "too many connections".into()
        })
    );
}

#[test]
fn unknown_untagged_responses_are_skipped_and_a_foreign_tag_is_not_imap() {
    let mut c = examined(None);
    assert_eq!(
        c.hear(b"* XWEIRD 1 (2 \"3\")\r\n* 3 EXISTS\r\n* OK [UIDNEXT 4] x\r\nb2 OK [SOMETHING NEW] done\r\n")
            .unwrap(),
        "b3 LOGOUT\r\n"
    );
    let mut c = examined(None);
    assert!(matches!(
        c.hear(b"b7 OK what\r\n"),
        Err(PollError::NotImap {
            step: Step::Examine,
            ..
        })
    ));
}

#[test]
fn garbage_is_not_imap_and_says_what_came() {
    let mut c = Client::new(config(Security::Plain, None));
    let e = c.hear(b"HTTP/1.1 400 Bad Request\r\n\x00\xff").unwrap_err();
    assert_eq!(
        e.to_string(),
        "the server sent something that is not IMAP (in its greeting): \"HTTP/1.1 400 Bad Request\""
    );
}

#[test]
fn each_attack_on_the_framing_is_refused_with_its_name() {
    let cases: [(&[u8], FrameError); 3] = [
        (
            &[b'(', b'x'].repeat(1000),
            FrameError::TooDeep { limit: 32 },
        ),
        (&[b'x'; 2 << 20], FrameError::LineTooLong { limit: 1 << 20 }),
        (
            b"* 1 FETCH (BODY[] {2147483648}\r\n",
            FrameError::LiteralTooLarge {
                announced: 2_147_483_648,
                limit: 1 << 20,
            },
        ),
    ];
    for (attack, error) in cases {
        let mut c = examined(None);
        let mut input = b"* 1 FETCH (BODYSTRUCTURE ".to_vec();
        input.extend(attack);
        assert_eq!(
            c.hear(&input),
            Err(PollError::Refused {
                step: Step::Examine,
                error
            })
        );
    }
    // Endless valid lines: the answer's cap.
    let mut config = config(Security::Plain, None);
    config.response_limit = 1000;
    let mut c = Client::new(config);
    c.hear(b"* OK ready\r\n").unwrap();
    let mut refused = None;
    for _ in 0..100 {
        if let Err(e) = c.hear(b"* OK still talking\r\n") {
            refused = Some(e);
            break;
        }
    }
    assert_eq!(
        refused,
        Some(PollError::ResponseTooLarge {
            step: Step::Login,
            limit: 1000
        })
    );
}

#[test]
fn silence_is_a_timeout_and_a_trickle_too() {
    let mut c = Client::new(config(Security::Plain, None));
    let start = c.now;
    assert_eq!(c.poll.deadline(), Some(start + TIMEOUT));
    c.poll.handle_timeout(start + TIMEOUT / 2).unwrap();
    assert_eq!(
        c.poll.handle_timeout(start + TIMEOUT),
        Err(PollError::Silent {
            step: Step::Greeting,
            timeout: TIMEOUT
        })
    );
    // Each command has its own time from when it is sent.
    let mut c = Client::new(config(Security::Plain, None));
    c.now += TIMEOUT / 2;
    c.hear(b"* OK ready\r\n").unwrap();
    assert_eq!(c.poll.deadline(), Some(c.now + TIMEOUT));
    c.hear(b"* OK a byte at a time, ").unwrap();
    assert_eq!(
        c.poll.handle_timeout(c.now + TIMEOUT),
        Err(PollError::Unfinished {
            step: Step::Login,
            timeout: TIMEOUT,
            received: 23
        })
    );
    assert_eq!(
        c.poll.handle_eof(),
        Err(PollError::Closed { step: Step::Login })
    );
}

/// A multipart BODYSTRUCTURE nested `depth` parentheses deep (the FETCH's own included).
fn nested_bodystructure(depth: usize) -> Vec<u8> {
    let mut line = b"* 1 FETCH (BODYSTRUCTURE ".to_vec();
    line.extend(b"(".repeat(depth - 1));
    line.extend(b"\"TEXT\" \"PLAIN\" NIL NIL NIL \"7BIT\" 1 1)");
    line.extend(b" \"MIXED\")".repeat(depth - 2));
    line.extend(b")\r\n");
    line
}

#[test]
fn nesting_up_to_the_cap_is_parsed_on_a_quarter_of_a_threads_stack() {
    // `buslab mail` looks on a thread with Rust's default 2 MiB stack.
    let cap = Limits::DEFAULT.depth as usize;
    std::thread::Builder::new()
        .stack_size(512 * 1024)
        .spawn(move || {
            let mut c = examined(None);
            // Deeper than imap-codec's own limit (8 body levels): skipped, not a failure.
            for depth in [3, 8, cap] {
                c.hear(&nested_bodystructure(depth)).unwrap();
            }
            assert_eq!(
                c.hear(b"* 3 EXISTS\r\n* OK [UIDNEXT 4] x\r\nb2 OK done\r\n")
                    .unwrap(),
                "b3 LOGOUT\r\n"
            );
            let mut c = examined(None);
            assert_eq!(
                c.hear(&nested_bodystructure(cap + 1)),
                Err(PollError::Refused {
                    step: Step::Examine,
                    error: FrameError::TooDeep { limit: 32 }
                })
            );
        })
        .unwrap()
        .join()
        .unwrap();
}
