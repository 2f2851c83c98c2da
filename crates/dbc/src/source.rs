//! The DBC text walked once: the grammar's items (can-dbc's grammar, can-dbc's types) with
//! the line each is on, indexed by message ID as the file writes it.
//!
//! can-dbc's own `Dbc` is not used: its `MessageId` keeps only 16 bits of an ID written
//! without the extended flag (opendbc's GM, FCA and VW files write 29-bit IDs that way), which
//! would merge messages, comments and value tables of different IDs; and it keeps no line
//! numbers for the errors found after the grammar.

use std::collections::HashMap;

use can_dbc::{
    AttributeDefault, AttributeDefinition, AttributeValue, AttributeValueType, Comment,
    ExtendedMultiplex, Message, SignalExtendedValueType, SignalExtendedValueTypeList,
    ValueDescription,
};
use can_dbc_pest::{DbcParser, Pair, Parser, Rule};

use crate::error::DbcError;

/// A message ID as the file writes it: bit 31 flags an extended ID.
pub(crate) type RawId = u64;

/// A `BO_` with its line and the line of each of its signals.
pub(crate) struct SourceMessage {
    pub line: usize,
    pub raw_id: RawId,
    pub message: Message,
    pub signal_lines: Vec<usize>,
}

/// An `SG_MUL_VAL_` with its line.
pub(crate) struct SourceMultiplex {
    pub line: usize,
    pub multiplex: ExtendedMultiplex,
}

/// Everything the model is resolved from. Where the file says a thing twice, the last word
/// counts (as in cantools).
#[derive(Default)]
pub(crate) struct Source {
    pub nodes: Vec<String>,
    pub messages: Vec<SourceMessage>,
    pub message_comments: HashMap<RawId, String>,
    pub signal_comments: HashMap<(RawId, String), String>,
    pub value_tables: HashMap<(RawId, String), Vec<(i64, String)>>,
    pub value_types: HashMap<(RawId, String), SignalExtendedValueType>,
    pub senders: HashMap<RawId, Vec<String>>,
    pub multiplex: HashMap<(RawId, String), Vec<SourceMultiplex>>,
    /// `BA_DEF_ BO_` and `BA_DEF_ SG_`: the attribute's type by name.
    pub message_attribute_types: HashMap<String, AttributeValueType>,
    pub signal_attribute_types: HashMap<String, AttributeValueType>,
    /// `BA_DEF_DEF_`.
    pub defaults: HashMap<String, AttributeValue>,
    pub message_attributes: HashMap<(RawId, String), AttributeValue>,
    pub signal_attributes: HashMap<(RawId, String, String), AttributeValue>,
    /// `SystemNodeLongSymbol`: a node's name beyond DBC's 32 characters.
    pub node_long_names: HashMap<String, String>,
}

/// Line numbers of byte offsets (pest's own `line_col` counts from the start of the text at
/// every call, quadratic over a file).
#[derive(Default)]
struct Lines {
    /// The offset of every line break.
    breaks: Vec<usize>,
}

impl Lines {
    fn new(text: &str) -> Self {
        Self {
            breaks: text.match_indices('\n').map(|(i, _)| i).collect(),
        }
    }

    /// The 1-based line of an item.
    fn of(&self, pair: &Pair<'_, Rule>) -> usize {
        self.breaks.partition_point(|&b| b < pair.as_span().start()) + 1
    }
}

/// The first message ID inside an item, as written.
fn raw_id(pair: &Pair<'_, Rule>, at: usize) -> Result<Option<RawId>, DbcError> {
    let Some(id) = pair
        .clone()
        .into_inner()
        .flatten()
        .find(|p| p.as_rule() == Rule::message_id)
    else {
        return Ok(None);
    };
    id.as_str()
        .parse()
        .map(Some)
        .map_err(|_| DbcError::Invalid {
            line: Some(at),
            what: format!("message ID {} is not a 32-bit number", id.as_str()),
        })
}

/// can-dbc's conversion of an item the grammar matched, its error given the item's line.
fn convert<'i, T>(pair: Pair<'i, Rule>, at: usize, what: &str) -> Result<T, DbcError>
where
    T: TryFrom<Pair<'i, Rule>, Error = can_dbc::DbcError>,
{
    T::try_from(pair).map_err(|e| DbcError::Invalid {
        line: Some(at),
        what: format!("{what}: {e}"),
    })
}

/// The text of a quoted string token, without its quotes.
fn unquote(pair: &Pair<'_, Rule>) -> String {
    let s = pair.as_str();
    s.strip_prefix('"')
        .and_then(|s| s.strip_suffix('"'))
        .unwrap_or(s)
        .to_string()
}

impl Source {
    /// A node's name: its long name when the file gives one.
    pub(crate) fn node_name(&self, short: &str) -> String {
        self.node_long_names
            .get(short)
            .cloned()
            .unwrap_or_else(|| short.to_string())
    }

    pub(crate) fn parse(text: &str) -> Result<Self, DbcError> {
        let file = DbcParser::parse(Rule::file, text)
            .map_err(|e| syntax(text, e))?
            .next()
            .expect("the grammar's file rule matched");
        let mut source = Source::default();
        let lines = Lines::new(text);
        for item in file.into_inner() {
            source.add(item, &lines)?;
        }
        Ok(source)
    }

    fn add(&mut self, item: Pair<'_, Rule>, lines: &Lines) -> Result<(), DbcError> {
        let at = lines.of(&item);
        let id = raw_id(&item, at)?;
        match item.as_rule() {
            Rule::nodes => {
                self.nodes.extend(
                    item.into_inner()
                        .filter(|p| p.as_rule() == Rule::node_name)
                        .map(|p| p.as_str().to_string()),
                );
            }
            Rule::message => {
                let signal_lines = item
                    .clone()
                    .into_inner()
                    .filter(|p| p.as_rule() == Rule::signal)
                    // A signal's pair starts with the line break before it.
                    .map(|p| {
                        p.into_inner()
                            .find(|q| q.as_rule() == Rule::signal_name)
                            .map_or(at, |q| lines.of(&q))
                    })
                    .collect();
                self.messages.push(SourceMessage {
                    line: at,
                    raw_id: id.expect("BO_ has an ID"),
                    message: convert(item, at, "message")?,
                    signal_lines,
                });
            }
            Rule::comment => match convert(item, at, "comment")? {
                // An empty comment is none (as cantools reads it).
                Comment::Message { comment, .. } | Comment::Signal { comment, .. }
                    if comment.is_empty() => {}
                Comment::Message { comment, .. } => {
                    self.message_comments.insert(id.expect("an ID"), comment);
                }
                Comment::Signal { name, comment, .. } => {
                    self.signal_comments
                        .insert((id.expect("an ID"), name), comment);
                }
                _ => {}
            },
            Rule::value_table_def => {
                if let ValueDescription::Signal {
                    name,
                    value_descriptions,
                    ..
                } = convert(item, at, "value table")?
                {
                    let table = value_descriptions
                        .into_iter()
                        .map(|d| (d.id, d.description))
                        .collect();
                    self.value_tables.insert((id.expect("an ID"), name), table);
                }
            }
            Rule::signal_value_type => {
                let v: SignalExtendedValueTypeList = convert(item, at, "signal value type")?;
                self.value_types.insert(
                    (id.expect("an ID"), v.signal_name),
                    v.signal_extended_value_type,
                );
            }
            Rule::message_transmitter => {
                let senders = self.senders.entry(id.expect("an ID")).or_default();
                for node in item
                    .into_inner()
                    .filter(|p| p.as_rule() == Rule::transmitter)
                {
                    senders.push(node.as_str().to_string());
                }
            }
            Rule::sg_mul_val => {
                let multiplex: ExtendedMultiplex = convert(item, at, "SG_MUL_VAL_")?;
                self.multiplex
                    .entry((id.expect("an ID"), multiplex.signal_name.clone()))
                    .or_default()
                    .push(SourceMultiplex {
                        line: at,
                        multiplex,
                    });
            }
            Rule::attr_def => match convert(item, at, "attribute definition")? {
                AttributeDefinition::Message(name, kind) => {
                    self.message_attribute_types.insert(name, kind);
                }
                AttributeDefinition::Signal(name, kind) => {
                    self.signal_attribute_types.insert(name, kind);
                }
                _ => {}
            },
            Rule::ba_def_def => {
                let d: AttributeDefault = convert(item, at, "attribute default")?;
                self.defaults.insert(d.name, d.value);
            }
            Rule::attr_value => self.add_attribute(item, at, id)?,
            _ => {}
        }
        Ok(())
    }

    /// `BA_ "name" BO_ id value;` and `BA_ "name" SG_ id signal value;` (can-dbc's type for
    /// these is private).
    fn add_attribute(
        &mut self,
        item: Pair<'_, Rule>,
        at: usize,
        id: Option<RawId>,
    ) -> Result<(), DbcError> {
        let mut parts = item.into_inner();
        let Some(name) = parts.next().map(|p| unquote(&p)) else {
            return Ok(());
        };
        let Some(object) = parts.next() else {
            return Ok(());
        };
        let rule = object.as_rule();
        if rule == Rule::node_var_val {
            let mut inner = object.into_inner();
            if let (Some(node), Some(value), "SystemNodeLongSymbol") =
                (inner.next(), inner.next(), name.as_str())
                && value.as_rule() == Rule::quoted_str
            {
                self.node_long_names
                    .insert(node.as_str().to_string(), unquote(&value));
            }
            return Ok(());
        }
        if !matches!(rule, Rule::msg_var_val | Rule::signal_var) {
            return Ok(());
        }
        let mut inner = object.into_inner().skip(1); // the message ID
        let signal = if rule == Rule::signal_var {
            inner.next().map(|p| p.as_str().to_string())
        } else {
            None
        };
        let Some(value) = inner.next() else {
            return Ok(());
        };
        let value = AttributeValue::try_from(value).map_err(|e| DbcError::Invalid {
            line: Some(at),
            what: format!("attribute {name}: {e}"),
        })?;
        let id = id.expect("an ID");
        match signal {
            Some(signal) => {
                self.signal_attributes.insert((id, signal, name), value);
            }
            None => {
                self.message_attributes.insert((id, name), value);
            }
        }
        Ok(())
    }
}

/// A syntax error: the farthest place the grammar reached and what it expected there.
///
/// pest's plain error points at the start of the item that failed (`BO_ 12 Foo 8 N` fails
/// at `BO_`, not at the missing `:`); its detailed tracking finds the place and the tokens.
/// The tracking is a process-wide switch that slows every parse, so it is on only while a
/// file that failed is parsed again.
fn syntax(text: &str, plain: can_dbc_pest::Error<Rule>) -> DbcError {
    pest::set_error_detail(true);
    let detailed = DbcParser::parse(Rule::file, text).err();
    pest::set_error_detail(false);
    let attempts = detailed.as_ref().and_then(|e| e.parse_attempts());
    let Some(attempts) = attempts else {
        let (line, column) = match plain.line_col {
            pest::error::LineColLocation::Pos(at) => at,
            pest::error::LineColLocation::Span(at, _) => at,
        };
        return DbcError::Syntax {
            line,
            column,
            expected: plain.variant.message().into_owned(),
        };
    };
    let at = attempts.max_position.min(text.len());
    let before = &text[..at];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().unwrap_or("").chars().count() + 1;
    let tokens: Vec<String> = attempts
        .expected_tokens()
        .iter()
        .map(ToString::to_string)
        .filter(|t| !matches!(t.as_str(), " " | "\t" | "\n" | "\r" | "\r\n" | "//"))
        .collect();
    // A new item could start here: every keyword is expected; name the common ones.
    let keyword = |t: &String| t.len() > 1 && t.chars().all(|c| c.is_ascii_uppercase() || c == '_');
    let mut tokens: Vec<String> = if tokens.iter().filter(|t| keyword(t)).count() > 5 {
        let mut rest: Vec<String> = tokens
            .iter()
            .filter(|t| !keyword(t))
            .map(|t| format!("{t:?}"))
            .collect();
        rest.push("a keyword (BO_, SG_, CM_, BA_, VAL_, ...)".into());
        rest
    } else {
        tokens.iter().map(|t| format!("{t:?}")).collect()
    };
    tokens.dedup();
    let found = text[at..]
        .split(['\n', '\r'])
        .next()
        .unwrap_or("")
        .chars()
        .take(24)
        .collect::<String>();
    let expected = match tokens.as_slice() {
        [] => plain.variant.message().into_owned(),
        [one] => format!("expected {one}"),
        [first @ .., last] => format!("expected {} or {last}", first.join(", ")),
    };
    DbcError::Syntax {
        line,
        column,
        expected: if found.is_empty() {
            format!("{expected}, found the end of the line")
        } else {
            format!("{expected}, found {found:?}")
        },
    }
}
