//! What the CAN client commands (`dump`, `send`, `gen`, `regs`, `status`) share: the `--bus`
//! option (or can-utils' interface first), opening the bus through the backend registry, and
//! waiting until frames were sent.

use std::time::Duration;

use anyhow::{Context, bail};
use buslab_backends::{BusUrl, Confirmation, DynBus, OpenOptions, resolve};
use buslab_canbus::{BusAdmin, NodeRef};

/// The common `--bus` option.
#[derive(clap::Args, Clone)]
pub struct BusOpt {
    /// The bus: vcan0 (buslab's bus on this machine), an interface (can0: SocketCAN), an
    /// SLCAN adapter's path (/dev/ttyACM0), or a URL: socketcand://HOST[:PORT][/CHANNEL],
    /// socketcan:IFACE, slcan:DEVICE[@BAUD][?bitrate=N&listen_only=1] (docs/transports.md).
    /// Default: the configuration's `bus` (docs/config.md), else vcan0.
    #[arg(long, value_name = "BUS", default_value = crate::config::get().bus_name.as_str(),
          value_parser = resolve)]
    pub bus: BusUrl,
}

/// The bus of a command that takes it as can-utils does (`IFACE` first) or as `--bus`: the
/// one given, else the configuration's.
pub fn one_bus(iface: Option<&BusUrl>, bus: Option<&BusUrl>) -> anyhow::Result<BusUrl> {
    match (iface, bus) {
        (Some(iface), Some(_)) => bail!("the bus is given twice: as IFACE ({iface}) and --bus"),
        (Some(url), None) | (None, Some(url)) => Ok(url.clone()),
        (None, None) => Ok(crate::config::get().bus.clone()),
    }
}

/// Opens the bus behind `url` with the backend its scheme names, and applies the
/// configuration's `[controller]` (the keys given) to this client's own node where the bus
/// has the setting: on buslab's bus, its own SJA1000 (docs/config.md). What the bus cannot
/// apply is said once per run, as a warning naming the setting and why.
pub fn open(url: &BusUrl) -> anyhow::Result<DynBus> {
    let options = open_options();
    let mut opened = buslab_backends::open_configured(url, &options)?;
    if options.controller.timing.is_some()
        && let Some(admin) = opened.bus.admin()
        && let Ok(status) = admin.node_status(None)
        && let Some(timing) = status.timing.filter(|t| !t.matches_bus)
    {
        // Applied, and the node cannot follow the bus: said at once, every time.
        tracing::warn!(
            "{url}: this node's bit rate from the configuration ({} bit/s, BTR0=0x{:02X} BTR1=0x{:02X}) is not the bus's ({} bit/s): it cannot communicate (docs/bus.md)",
            timing.bitrate,
            timing.btr0,
            timing.btr1,
            status.bus.bitrate
        );
    }
    // Once per bus in a run: `dump` reopens its bus after a drop, `bridge` opens two.
    static TOLD: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());
    let first = {
        let mut told = TOLD
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let name = url.to_string();
        let first = !told.contains(&name);
        if first {
            told.push(name);
        }
        first
    };
    if first {
        for (part, why) in opened.controller.not_applied() {
            tracing::warn!(
                "{url}: {} from the configuration not applied: {why}",
                part.describe()
            );
        }
        if !opened.controller.is_empty() {
            tracing::info!("{url}: controller settings:\n{}", opened.controller);
        }
    }
    Ok(opened.bus)
}

/// How buses are opened with the configuration: its `[controller]` (the keys given) and the
/// MQTT broker's credentials (`[mqtt]` or the environment, never the command line).
pub fn open_options() -> OpenOptions {
    let config = crate::config::get();
    OpenOptions {
        controller: config.controller_settings,
        mqtt_credentials: config.mqtt_credentials.clone(),
        ..OpenOptions::default()
    }
}

/// The bus's administration side, or an error saying `what` needs a buslab bus.
pub fn admin<'a>(
    bus: &'a mut DynBus,
    url: &BusUrl,
    what: &str,
) -> anyhow::Result<&'a mut dyn BusAdmin> {
    match bus.admin() {
        Some(admin) => Ok(admin),
        None => bail!("{url}: the server has no {what} (not a buslab bus)"),
    }
}

/// Names this client's node if asked to; a plain socketcand has no node names (a warning).
pub fn set_name(bus: &mut DynBus, url: &BusUrl, name: Option<&str>) -> anyhow::Result<()> {
    let Some(name) = name else {
        return Ok(());
    };
    match bus.admin() {
        Some(admin) => admin
            .set_name(name)
            .with_context(|| format!("cannot name this node {name:?}")),
        None => {
            tracing::warn!("{url} is not a buslab bus: --name {name} is ignored");
            Ok(())
        }
    }
}

/// `--node` as the server names nodes: a number (connection order from 1) or a name.
pub fn node_ref(text: &str) -> NodeRef {
    NodeRef::parse(text)
}

/// Bits a classic frame takes on the wire at most, intermission included.
pub use buslab_can::wire::LONGEST_FRAME_BITS as WORST_FRAME_BITS;

/// Waits until the `count` frames this client sent were transmitted or given up
/// ([`buslab_backends::confirm_sent`]). A plain socketcand cannot tell: a warning, and
/// success.
pub fn confirm_sent(
    bus: &mut DynBus,
    url: &BusUrl,
    count: u64,
    timeout: Duration,
) -> anyhow::Result<()> {
    match buslab_backends::confirm_sent(&mut **bus, count, timeout)? {
        Confirmation::AllSent => {}
        Confirmation::Unconfirmable => {
            if matches!(url, BusUrl::Socketcand { .. }) {
                tracing::warn!(
                    "{url} is not a buslab bus: cannot confirm that the {count} frame(s) were sent"
                );
            }
        }
    }
    Ok(())
}
