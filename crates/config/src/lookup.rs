//! Finding the file, reading it, and laying the environment and `--set` over it.

use std::ffi::OsString;
use std::fmt;
use std::path::{Path, PathBuf};

use toml::de::{DeTable, DeValue};

use super::keys::{self, KEYS, SECTIONS, Settings, Sources};
use super::value::Raw;
use super::{
    ConfigError, ENV_FILE, ENV_MAIL_PASSWORD, FILE_NAME, Loaded, MAX_FILE_BYTES, Password, Source,
};

/// What the command line says about the configuration.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Lookup {
    /// `--config FILE`.
    pub file: Option<PathBuf>,
    /// `--no-config`.
    pub no_file: bool,
    /// `--set KEY=VALUE`, in order.
    pub sets: Vec<String>,
}

impl Lookup {
    /// The options from the raw arguments, before clap parses them (the other options take
    /// their defaults from the configuration): the words before the subcommand only.
    pub fn scan(args: &[OsString]) -> Self {
        let mut lookup = Lookup::default();
        let mut words = args.iter().skip(1);
        while let Some(word) = words.next() {
            let text = word.to_string_lossy();
            if let Some(v) = text.strip_prefix("--config=") {
                lookup.file = Some(PathBuf::from(v));
            } else if text == "--config" {
                lookup.file = words.next().map(PathBuf::from);
            } else if text == "--no-config" {
                lookup.no_file = true;
            } else if let Some(v) = text.strip_prefix("--set=") {
                lookup.sets.push(v.to_string());
            } else if text == "--set" {
                lookup
                    .sets
                    .extend(words.next().map(|v| v.to_string_lossy().into_owned()));
            } else if !text.starts_with('-') || text == "--" {
                // The subcommand (the other top-level options are flags).
                break;
            }
        }
        lookup
    }
}

/// How the configuration file was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Found {
    /// `--config FILE`.
    CommandLine,
    /// `$BUSLAB_CONFIG`.
    Environment,
    /// `./buslab.toml`.
    CurrentDirectory,
    /// The user's configuration directory.
    UserDirectory,
}

impl fmt::Display for Found {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Found::CommandLine => "from --config",
            Found::Environment => "from $BUSLAB_CONFIG",
            Found::CurrentDirectory => "in the current directory",
            Found::UserDirectory => "in the user's configuration directory",
        })
    }
}

/// Loads the configuration: the defaults, then the first file of `--config`,
/// `$BUSLAB_CONFIG`, `cwd/buslab.toml` and `user_file` (a named file must exist, the others
/// are looked for), then the environment (`env`), then `--set`.
pub fn load(
    lookup: &Lookup,
    env: &dyn Fn(&str) -> Option<String>,
    cwd: &Path,
    user_file: Option<&Path>,
) -> Result<Loaded, ConfigError> {
    let file = find(lookup, env, cwd, user_file);
    let text = match &file {
        Some((path, found)) => Some(buslab_fs::read_text_limited(path, MAX_FILE_BYTES).map_err(
            |source| ConfigError::Read {
                path: path.clone(),
                found: *found,
                source,
            },
        )?),
        None => None,
    };
    let file = file.zip(text);
    load_text(
        file.as_ref()
            .map(|((path, found), text)| (path.as_path(), *found, text.as_str())),
        env,
        &lookup.sets,
    )
}

/// What [`load`] does once the file is read: `file` (its path, how it was found, its text;
/// `None`: no file) over the defaults, then the environment (`env`), then `sets`
/// (`KEY=VALUE`). Touches no file: the path only names where a value came from.
pub fn load_text(
    file: Option<(&Path, Found, &str)>,
    env: &dyn Fn(&str) -> Option<String>,
    sets: &[String],
) -> Result<Loaded, ConfigError> {
    let mut settings = Settings::default();
    let mut sources = Sources::defaults();
    if let Some((path, _, text)) = file {
        read_file(path, text, &mut settings, &mut sources)?;
    }
    for (i, key) in KEYS.iter().enumerate() {
        let var = key.env();
        if let Some(text) = env(&var).filter(|t| !t.is_empty()) {
            let source = Source::Env(var);
            let raw = Raw::Text(text.clone());
            apply(i, &raw, text, source, &mut settings, &mut sources)?;
        }
    }
    for set in sets {
        let (name, text) = set
            .split_once('=')
            .ok_or_else(|| ConfigError::SetSyntax(set.clone()))?;
        let name = name.trim();
        let i = keys::index(name).ok_or_else(|| unknown(name, Source::CommandLine))?;
        if keys::SECRET_KEYS.contains(&KEYS[i].name) {
            return Err(ConfigError::SecretOnCommandLine(KEYS[i].name));
        }
        let raw = Raw::Text(text.to_string());
        apply(
            i,
            &raw,
            text.to_string(),
            Source::CommandLine,
            &mut settings,
            &mut sources,
        )?;
    }
    let mut config = settings.finish(&sources)?;
    config.mail.password = env(ENV_MAIL_PASSWORD)
        .filter(|p| !p.is_empty())
        .map(Password::new);
    Ok(Loaded {
        config,
        settings,
        file: file.map(|(path, found, _)| (path.to_path_buf(), found)),
        sources,
    })
}

/// The file to read, if any.
fn find(
    lookup: &Lookup,
    env: &dyn Fn(&str) -> Option<String>,
    cwd: &Path,
    user_file: Option<&Path>,
) -> Option<(PathBuf, Found)> {
    if lookup.no_file {
        return None;
    }
    if let Some(path) = &lookup.file {
        return Some((path.clone(), Found::CommandLine));
    }
    if let Some(path) = env(ENV_FILE).filter(|p| !p.is_empty()) {
        return Some((PathBuf::from(path), Found::Environment));
    }
    let here = cwd.join(FILE_NAME);
    if here.exists() {
        return Some((here, Found::CurrentDirectory));
    }
    user_file
        .filter(|p| p.exists())
        .map(|p| (p.to_path_buf(), Found::UserDirectory))
}

fn apply(
    i: usize,
    raw: &Raw,
    shown: String,
    source: Source,
    settings: &mut Settings,
    sources: &mut Sources,
) -> Result<(), ConfigError> {
    let key = &KEYS[i];
    key.apply(settings, raw)
        .map_err(|allowed| ConfigError::Value {
            origin: source.clone(),
            key: key.name,
            value: if keys::hidden(key.name) {
                "(not shown)".to_string()
            } else {
                shown
            },
            allowed,
        })?;
    sources.set(i, source);
    Ok(())
}

/// Reads the file's keys into `settings`.
fn read_file(
    path: &Path,
    text: &str,
    settings: &mut Settings,
    sources: &mut Sources,
) -> Result<(), ConfigError> {
    let line_of = |offset: usize| text[..offset.min(text.len())].matches('\n').count() + 1;
    let table = DeTable::parse(text).map_err(|e| {
        let offset = e.span().map_or(0, |s| s.start);
        let line = line_of(offset);
        let line_start = text[..offset.min(text.len())]
            .rfind('\n')
            .map_or(0, |n| n + 1);
        ConfigError::Syntax {
            path: path.to_path_buf(),
            line,
            column: text[line_start..offset.min(text.len())].chars().count() + 1,
            message: e.message().trim_end().to_string(),
        }
    })?;
    let mut entries = Vec::new();
    flatten(table.get_ref(), "", &mut entries);
    for (name, span, value) in entries {
        let source = Source::File {
            path: path.to_path_buf(),
            line: line_of(span),
        };
        let i = keys::index(&name).ok_or_else(|| unknown(&name, source.clone()))?;
        let shown = text
            .get(value.clone())
            .map_or_else(String::new, |s| s.trim().to_string());
        let raw = match &value_at(table.get_ref(), &name) {
            Some(v) => Raw::from_toml(v),
            None => Raw::Other("table"),
        };
        apply(i, &raw, shown, source, settings, sources)?;
    }
    Ok(())
}

/// Every leaf of the file as (`section.key`, offset of the key, span of the value); the
/// known sections are opened, every other table is a leaf (an unknown key or a wrong type).
fn flatten(
    table: &DeTable<'_>,
    prefix: &str,
    out: &mut Vec<(String, usize, std::ops::Range<usize>)>,
) {
    for (key, value) in table {
        let name = format!("{prefix}{}", key.get_ref());
        match value.get_ref() {
            DeValue::Table(inner) if prefix.is_empty() && SECTIONS.contains(&name.as_str()) => {
                flatten(inner, &format!("{name}."), out);
            }
            _ => out.push((name, key.span().start, value.span())),
        }
    }
}

fn value_at<'a>(table: &'a DeTable<'a>, name: &str) -> Option<&'a DeValue<'a>> {
    let (section, leaf) = match name.split_once('.') {
        Some((s, l)) => (Some(s), l),
        None => (None, name),
    };
    let table = match section {
        Some(s) => match table.get(s)?.get_ref() {
            DeValue::Table(t) => t,
            _ => return None,
        },
        None => table,
    };
    Some(table.get(leaf)?.get_ref())
}

fn unknown(name: &str, source: Source) -> ConfigError {
    if name == "mail.password" || name == "password" {
        return ConfigError::PasswordNotHere { origin: source };
    }
    ConfigError::UnknownKey {
        origin: source,
        key: name.to_string(),
        hint: suggestion(name).map_or_else(String::new, |s| format!(" (did you mean {s}?)")),
    }
}

/// The known key closest to `name`, if one is close; JerryCAN's names map to buslab's.
fn suggestion(name: &str) -> Option<String> {
    let leaf = name.rsplit_once('.').map_or(name, |(_, l)| l);
    if let Some(ours) = KEYS.iter().find(|k| {
        k.jerrycan
            .is_some_and(|theirs| theirs.eq_ignore_ascii_case(leaf))
    }) {
        return Some(format!("{}, JerryCAN's {leaf}", ours.name));
    }
    let mut best: Option<(f64, &str)> = None;
    for key in KEYS {
        // The full name (`mail.hots`), or the name without its section (`hots` at the top,
        // `mail.bitrate` for `controller.bitrate`).
        let score =
            strsim::jaro_winkler(name, key.name).max(strsim::jaro_winkler(leaf, key.leaf()));
        if best.is_none_or(|(b, _)| score > b) {
            best = Some((score, key.name));
        }
    }
    if !name.contains('.')
        && let Some(section) = SECTIONS
            .iter()
            .find(|s| strsim::jaro_winkler(name, s) > 0.85)
    {
        return Some(format!("[{section}]"));
    }
    best.filter(|(score, _)| *score > 0.85)
        .map(|(_, k)| k.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn os(words: &[&str]) -> Vec<OsString> {
        words.iter().map(OsString::from).collect()
    }

    #[test]
    fn the_options_are_found_before_clap_parses() {
        let l = Lookup::scan(&os(&[
            "buslab",
            "-v",
            "--config",
            "a.toml",
            "--set",
            "bus=can0",
            "--set=mail_id=0x701",
            "-q",
            "dump",
        ]));
        assert_eq!(l.file, Some(PathBuf::from("a.toml")));
        assert_eq!(l.sets, ["bus=can0", "mail_id=0x701"]);
        let l = Lookup::scan(&os(&["buslab", "cpu196", "start", "--config", "3"]));
        assert_eq!(l, Lookup::default(), "a subcommand's --config is its own");
        let l = Lookup::scan(&os(&["buslab", "--", "--config", "x"]));
        assert_eq!(l, Lookup::default(), "nothing after --");
        assert!(Lookup::scan(&os(&["buslab", "--no-config", "dump"])).no_file);
    }

    #[test]
    fn suggestions_for_typos_and_jerrycan_names() {
        assert_eq!(suggestion("mail.hots").as_deref(), Some("mail.host"));
        assert_eq!(
            suggestion("controller.bitrat").as_deref(),
            Some("controller.bitrate")
        );
        assert_eq!(
            suggestion("idloader").as_deref(),
            Some("loader_id, JerryCAN's idloader")
        );
        assert_eq!(suggestion("mial").as_deref(), Some("[mail]"));
        assert_eq!(suggestion("zzzzzz"), None);
    }
}
