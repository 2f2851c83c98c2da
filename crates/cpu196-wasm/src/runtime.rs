//! The runtime: one wasmi engine (an interpreter: no JIT, deterministic, fuel-metered) and the
//! kernel API as host functions; a module instantiated per START becomes a [`UserProgram`].
//!
//! A hook runs against a copy of what the kernel offers (time, arguments, A/D values, PWM) and
//! records what it asks for; the effects go to the kernel's [`Api`] in order once it returns,
//! also after a trap (what it did before stays done, as on a CPU).

use buslab_cpu196::codes::Alert;
use buslab_cpu196::flash::Flash;
use buslab_cpu196::message::{DisplayFormat, FileMode};
use buslab_cpu196::pic::{PicCommand, PicEvent};
use buslab_cpu196::program::{Api, Flow, LoadError, ModuleRuntime, UserProgram};
use wasmi::{
    Caller, CompilationMode, Config, EnforcedLimits, Engine, Extern, Func, Linker, Store,
    StoreLimits, StoreLimitsBuilder, TrapCode,
};

use crate::abi::{
    HOOK_FUEL, HOOK_TIME_LIMIT_US, Hook, IMPORT_MODULE, MAX_CALL_DEPTH, MAX_MEMORY_PAGES,
    MAX_OUTPUT_PER_CALL, MAX_TABLE_ELEMENTS, STOP_BIT,
};
use crate::layout;
use crate::validate::{self, ModuleError, ModuleInfo};

/// A misuse of the kernel API: the program is stopped with this message.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
struct Misuse(String);

impl wasmi::errors::HostError for Misuse {}

fn misuse(message: String) -> wasmi::Error {
    wasmi::Error::host(Misuse(message))
}

/// What a hook asked of the kernel, replayed on its [`Api`] in order.
#[derive(Debug)]
enum Effect {
    Display {
        format: DisplayFormat,
        data: Vec<u8>,
        newline: bool,
    },
    Virtual {
        channel: u8,
        value12: u16,
    },
    Alert(u8),
    Open {
        name: String,
        mode: FileMode,
    },
    Write {
        file: u8,
        data: Vec<u8>,
    },
    Read {
        file: u8,
        len: u8,
    },
    Close(u8),
    Pic(PicCommand),
}

/// The store's data: the kernel's offer for the current call and what the call asked for.
struct Host {
    limits: StoreLimits,
    now_ns: u64,
    args: [u16; 7],
    ad: [u16; 8],
    pic_ad: [u16; 8],
    pwm: [u8; 3],
    next_file: u8,
    effects: Vec<Effect>,
    /// Bytes of messages queued for the PC in this call.
    output: usize,
    /// The bytes of the current event (RS_prog's parameters, Main_Fread's data).
    event: Vec<u8>,
    /// User commands declared with `user_command`.
    commands: Vec<(u8, u8)>,
}

impl Host {
    fn new(args: [u16; 7]) -> Self {
        Self {
            limits: StoreLimitsBuilder::new()
                .memory_size(MAX_MEMORY_PAGES as usize * 65536)
                .memories(1)
                .tables(1)
                .table_elements(MAX_TABLE_ELEMENTS)
                .instances(1)
                .build(),
            now_ns: 0,
            args,
            ad: [0; 8],
            pic_ad: [0; 8],
            pwm: [0; 3],
            next_file: 0,
            effects: Vec::new(),
            output: 0,
            event: Vec::new(),
            commands: Vec::new(),
        }
    }

    fn begin(&mut self, k: &Api, event: &[u8]) {
        self.now_ns = k.now_ns.get();
        self.args = k.args;
        self.ad = k.ad;
        self.pic_ad = k.pic_ad;
        self.pwm = *k.pwm;
        self.next_file = k.next_file();
        self.effects.clear();
        self.output = 0;
        self.event.clear();
        self.event.extend_from_slice(event);
    }

    fn finish(&mut self, k: &mut Api) {
        *k.pwm = self.pwm;
        for effect in self.effects.drain(..) {
            match effect {
                Effect::Display {
                    format,
                    data,
                    newline,
                } => k.display(format, &data, newline),
                Effect::Virtual { channel, value12 } => k.virtual_channel(channel, value12),
                Effect::Alert(a) => k.alert(Alert(a)),
                Effect::Open { name, mode } => {
                    k.fopen(&name, mode);
                }
                Effect::Write { file, data } => k.fwrite(file, &data),
                Effect::Read { file, len } => k.fread(file, len),
                Effect::Close(file) => k.fclose(file),
                Effect::Pic(c) => k.pic_command(c),
            }
        }
    }

    /// Queues `effect`, which sends `bytes` to the PC, within the per-call allowance.
    fn emit(&mut self, call: &str, effect: Effect, bytes: usize) -> Result<(), wasmi::Error> {
        self.output += bytes;
        if self.output > MAX_OUTPUT_PER_CALL {
            return Err(misuse(format!(
                "{call}: more than {MAX_OUTPUT_PER_CALL} bytes for the PC in one call (the kernel's transmit FIFO)"
            )));
        }
        self.effects.push(effect);
        Ok(())
    }
}

/// `value` as an integer in `range`, or the misuse naming the call, the argument and the range.
fn within(
    call: &str,
    what: &str,
    value: i32,
    range: core::ops::RangeInclusive<i32>,
) -> Result<u32, wasmi::Error> {
    if range.contains(&value) {
        Ok(value as u32)
    } else {
        Err(misuse(format!(
            "{call}: {what} {value} is out of range {}..{}",
            range.start(),
            range.end()
        )))
    }
}

fn memory(caller: &Caller<'_, Host>, call: &str) -> Result<wasmi::Memory, wasmi::Error> {
    caller
        .get_export("memory")
        .and_then(Extern::into_memory)
        .ok_or_else(|| misuse(format!("{call}: the module exports no `memory`")))
}

fn read_memory(
    caller: &Caller<'_, Host>,
    call: &str,
    ptr: i32,
    len: usize,
) -> Result<Vec<u8>, wasmi::Error> {
    let data = memory(caller, call)?.data(caller);
    let start = ptr as u32 as usize;
    start
        .checked_add(len)
        .and_then(|end| data.get(start..end))
        .map(<[u8]>::to_vec)
        .ok_or_else(|| {
            misuse(format!(
                "{call}: bytes {start}..{} are outside the module's memory ({} bytes)",
                start as u64 + len as u64,
                data.len()
            ))
        })
}

type Res<T = ()> = Result<T, wasmi::Error>;

/// Defines every import of [`abi::IMPORTS`] (a test checks that the two agree).
fn define(linker: &mut Linker<Host>) -> Result<(), wasmi::errors::LinkerError> {
    let m = IMPORT_MODULE;
    linker.func_wrap(
        m,
        "affiche",
        |mut caller: Caller<'_, Host>, n: i32, format: i32, ptr: i32| -> Res {
            let call = "affiche";
            let code = within(call, "format", format, 0..=15)?;
            let Some(f) = DisplayFormat::from_code(code as u8) else {
                return Err(misuse(format!(
                    "affiche: format {format} is none (0 text, 2..7 numbers; +8 newline)"
                )));
            };
            let n = within(call, "count", n, 0..=MAX_OUTPUT_PER_CALL as i32)? as usize;
            let len = if f.is_word() { 2 * n } else { n };
            let data = read_memory(&caller, call, ptr, len)?;
            let bytes = len + 4 * len.div_ceil(255).max(1);
            let effect = Effect::Display {
                format: f,
                data,
                newline: code & 8 != 0,
            };
            caller.data_mut().emit(call, effect, bytes)
        },
    )?;
    linker.func_wrap(
        m,
        "fopen",
        |mut caller: Caller<'_, Host>, n: i32, ptr: i32, mode: i32| -> Res<i32> {
            let call = "fopen";
            let n = within(call, "name length", n, 1..=255)? as usize;
            let mode = match within(call, "mode", mode, 0..=1)? {
                0 => FileMode::Read,
                _ => FileMode::Write,
            };
            let name = String::from_utf8(read_memory(&caller, call, ptr, n)?)
                .map_err(|_| misuse("fopen: the file name is not UTF-8".into()))?;
            let host = caller.data_mut();
            let file = host.next_file;
            host.next_file = host.next_file.wrapping_add(1);
            host.emit(call, Effect::Open { name, mode }, n + 5)?;
            Ok(i32::from(file))
        },
    )?;
    linker.func_wrap(
        m,
        "fwrite",
        |mut caller: Caller<'_, Host>, f: i32, n: i32, ptr: i32| -> Res {
            let call = "fwrite";
            let file = within(call, "file", f, 0..=255)? as u8;
            let n = within(call, "count", n, 0..=MAX_OUTPUT_PER_CALL as i32)? as usize;
            let data = read_memory(&caller, call, ptr, n)?;
            let bytes = n + 5 * n.div_ceil(255).max(1);
            caller
                .data_mut()
                .emit(call, Effect::Write { file, data }, bytes)
        },
    )?;
    linker.func_wrap(
        m,
        "fread",
        |mut caller: Caller<'_, Host>, f: i32, n: i32| -> Res {
            let call = "fread";
            let file = within(call, "file", f, 0..=255)? as u8;
            let len = within(call, "count", n, 1..=255)? as u8;
            caller.data_mut().emit(call, Effect::Read { file, len }, 5)
        },
    )?;
    linker.func_wrap(m, "fclose", |mut caller: Caller<'_, Host>, f: i32| -> Res {
        let file = within("fclose", "file", f, 0..=255)? as u8;
        caller.data_mut().emit("fclose", Effect::Close(file), 4)
    })?;
    // Virtual channels travel as 12-bit values (FB); the 16- and 8-bit forms are scaled.
    for (name, max, to12) in [
        (
            "emission_canal_virtuel_16bits",
            0xFFFF,
            (|d| d >> 4) as fn(u32) -> u32,
        ),
        ("emission_canal_virtuel_12bits", 0xFFF, |d| d),
        ("emission_canal_virtuel_8bits", 0xFF, |d| d << 4),
    ] {
        linker.func_wrap(
            m,
            name,
            move |mut caller: Caller<'_, Host>, n: i32, d: i32| -> Res {
                let channel = within(name, "channel", n, 0..=7)? as u8;
                let value12 = to12(within(name, "value", d, 0..=max)?) as u16;
                caller
                    .data_mut()
                    .emit(name, Effect::Virtual { channel, value12 }, 3)
            },
        )?;
    }
    linker.func_wrap(
        m,
        "pwm",
        |mut caller: Caller<'_, Host>, n: i32, c: i32| -> Res {
            let n = within("pwm", "output", n, 0..=2)? as usize;
            caller.data_mut().pwm[n] = within("pwm", "value", c, 0..=255)? as u8;
            Ok(())
        },
    )?;
    linker.func_wrap(m, "alerte", |mut caller: Caller<'_, Host>, a: i32| -> Res {
        // The user range: the kernel's own alerts (battery, link, ...) are its to raise.
        let a = within("alerte", "alert", a, 0x30..=0x3F)? as u8;
        caller.data_mut().emit("alerte", Effect::Alert(a), 2)
    })?;
    linker.func_wrap(
        m,
        "ad_voie",
        |caller: Caller<'_, Host>, n: i32| -> Res<i32> {
            let n = within("ad_voie", "channel", n, 0..=7)? as usize;
            Ok(i32::from(caller.data().ad[n]))
        },
    )?;
    linker.func_wrap(
        m,
        "ad_pic",
        |caller: Caller<'_, Host>, n: i32| -> Res<i32> {
            let n = within("ad_pic", "channel", n, 0..=7)? as usize;
            Ok(i32::from(caller.data().pic_ad[n]))
        },
    )?;
    linker.func_wrap(m, "arg", |caller: Caller<'_, Host>, i: i32| -> Res<i32> {
        let i = within("arg", "argument", i, 0..=6)? as usize;
        Ok(i32::from(caller.data().args[i]))
    })?;
    linker.func_wrap(m, "now_us", |caller: Caller<'_, Host>| -> i64 {
        (caller.data().now_ns / 1000) as i64
    })?;
    linker.func_wrap(
        m,
        "wr_pic_pwm",
        |mut caller: Caller<'_, Host>, v: i32| -> Res {
            let value = within("wr_pic_pwm", "value", v, 0..=1023)? as u16;
            let c = PicCommand::WritePwm { n: 0, value };
            caller.data_mut().emit("wr_pic_pwm", Effect::Pic(c), 0)
        },
    )?;
    linker.func_wrap(
        m,
        "wr_pic_reference",
        |mut caller: Caller<'_, Host>, v: i32| -> Res {
            let v = within("wr_pic_reference", "value", v, 0..=31)? as u8;
            let c = Effect::Pic(PicCommand::WriteVref(v));
            caller.data_mut().emit("wr_pic_reference", c, 0)
        },
    )?;
    linker.func_wrap(
        m,
        "wr_pic_sci",
        |mut caller: Caller<'_, Host>, b: i32| -> Res {
            let b = within("wr_pic_sci", "byte", b, 0..=255)? as u8;
            let c = Effect::Pic(PicCommand::SciWrite(b));
            caller.data_mut().emit("wr_pic_sci", c, 0)
        },
    )?;
    linker.func_wrap(
        m,
        "wr_pic_user",
        |mut caller: Caller<'_, Host>, b: i32| -> Res {
            let b = within("wr_pic_user", "byte", b, 0..=255)? as u8;
            let c = Effect::Pic(PicCommand::User(b));
            caller.data_mut().emit("wr_pic_user", c, 0)
        },
    )?;
    linker.func_wrap(
        m,
        "user_command",
        |mut caller: Caller<'_, Host>, cmd: i32, n: i32| -> Res {
            let cmd = within("user_command", "command", cmd, 0..=0xEF)? as u8;
            let len = within("user_command", "parameter count", n, 0..=255)? as u8;
            let commands = &mut caller.data_mut().commands;
            commands.retain(|(c, _)| *c != cmd);
            commands.push((cmd, len));
            Ok(())
        },
    )?;
    linker.func_wrap(
        m,
        "event_data",
        |mut caller: Caller<'_, Host>, ptr: i32, max: i32| -> Res<i32> {
            let call = "event_data";
            let max = within(call, "size", max, 0..=i32::MAX)? as usize;
            let memory = memory(&caller, call)?;
            let (data, host) = memory.data_and_store_mut(&mut caller);
            let n = host.event.len().min(max);
            let start = ptr as u32 as usize;
            let Some(slot) = start
                .checked_add(n)
                .and_then(|end| data.get_mut(start..end))
            else {
                return Err(misuse(format!(
                    "{call}: bytes {start}..{} are outside the module's memory ({} bytes)",
                    start as u64 + n as u64,
                    data.len()
                )));
            };
            slot.copy_from_slice(&host.event[..n]);
            Ok(n as i32)
        },
    )?;
    Ok(())
}

/// Runs WebAssembly user programs; install it with
/// `board.registry_mut().set_module_runtime(Box::new(WasmRuntime::new()))`.
pub struct WasmRuntime {
    engine: Engine,
    linker: Linker<Host>,
}

impl Default for WasmRuntime {
    fn default() -> Self {
        Self::new()
    }
}

impl WasmRuntime {
    pub fn new() -> Self {
        let mut config = Config::default();
        config
            .consume_fuel(true)
            // Everything a module runs is in its hooks, within their fuel.
            .allow_start_fn(false)
            // The whole module is checked when it is loaded, not as it runs.
            .compilation_mode(CompilationMode::Eager)
            .enforced_limits(EnforcedLimits::strict())
            .set_max_recursion_depth(MAX_CALL_DEPTH);
        let engine = Engine::new(&config);
        let mut linker = Linker::new(&engine);
        define(&mut linker).expect("each kernel service is defined once");
        Self { engine, linker }
    }

    /// Checks `bytes` as the board would before running them: the contract, then a trial
    /// instantiation (memory within the limit, data segments in place).
    pub fn check(&self, bytes: &[u8]) -> Result<ModuleInfo, ModuleError> {
        self.instantiate(bytes, [0; 7]).map(|p| p.info)
    }

    /// A program from a module's bytes, with its configuration set's arguments.
    pub fn instantiate(&self, bytes: &[u8], args: [u16; 7]) -> Result<WasmProgram, ModuleError> {
        let (module, info) = validate::check(&self.engine, bytes)?;
        let mut store = Store::new(&self.engine, Host::new(args));
        store.limiter(|host| &mut host.limits);
        store.set_fuel(HOOK_FUEL).expect("fuel metering is on");
        let instance = self
            .linker
            .instantiate_and_start(&mut store, &module)
            .map_err(|e| ModuleError::Instantiate(e.to_string()))?;
        let hooks = Hook::ALL.map(|h| instance.get_func(&store, h.name()));
        Ok(WasmProgram {
            store,
            hooks,
            info,
            stopped: false,
        })
    }
}

impl ModuleRuntime for WasmRuntime {
    fn load(
        &self,
        flash: &Flash,
        bank: u8,
        block: u8,
        args: [u16; 7],
    ) -> Result<Box<dyn UserProgram>, LoadError> {
        let stored = layout::read(flash, bank, block)?;
        let program = self.instantiate(&stored.bytes, args)?;
        tracing::debug!(
            name = stored.name,
            bytes = stored.bytes.len(),
            "module loaded from bank {bank} block {block:02X}h"
        );
        Ok(Box::new(program))
    }
}

/// A module instantiated for one run.
pub struct WasmProgram {
    store: Store<Host>,
    hooks: [Option<Func>; 9],
    info: ModuleInfo,
    /// The kernel stopped it (fuel, trap, misuse): no hook runs again.
    stopped: bool,
}

/// Why a call failed, for the user.
fn explain(e: &wasmi::Error) -> String {
    if e.as_trap_code() == Some(TrapCode::OutOfFuel) {
        return format!(
            "ran out of fuel: more than {} ms of CPU time ({HOOK_FUEL} instructions) in one call; an endless loop?",
            HOOK_TIME_LIMIT_US / 1000
        );
    }
    if let Some(m) = e.downcast_ref::<Misuse>() {
        return m.0.clone();
    }
    format!("trapped: {e}")
}

impl WasmProgram {
    pub fn info(&self) -> &ModuleInfo {
        &self.info
    }

    fn has(&self, hook: Hook) -> bool {
        self.hooks[hook as usize].is_some()
    }

    /// Calls `hook` (if the module has it) with `event` as its bytes; its result word, if
    /// any, becomes the flow.
    fn call(
        &mut self,
        k: &mut Api,
        hook: Hook,
        event: &[u8],
        invoke: impl FnOnce(Func, &mut Store<Host>) -> Result<Option<i32>, wasmi::Error>,
    ) -> Flow {
        let Some(func) = self.hooks[hook as usize].filter(|_| !self.stopped) else {
            return Flow::CONTINUE;
        };
        self.store.data_mut().begin(k, event);
        self.store.set_fuel(HOOK_FUEL).expect("fuel metering is on");
        let result = invoke(func, &mut self.store);
        self.store.data_mut().finish(k);
        match result {
            Ok(None) => Flow::CONTINUE,
            Ok(Some(r)) if (r as u32) >> 17 == 0 => {
                Flow::from_raw(r as u32 & STOP_BIT != 0, r as u16)
            }
            Ok(Some(r)) => self.stop(
                k,
                hook,
                format!(
                    "returned {:X}h; a hook returns ContExec 8000h, StopExec 18000h or a START word (bits 17..31 zero)",
                    r as u32
                ),
            ),
            Err(e) => self.stop(k, hook, explain(&e)),
        }
    }

    /// The kernel stops the program: an alert, a line on the THREAD display, the lower loop
    /// ends (without `fin_prog`: the program is no longer trusted).
    fn stop(&mut self, k: &mut Api, hook: Hook, why: String) -> Flow {
        self.stopped = true;
        tracing::warn!("user program stopped in {}: {why}", hook.name());
        k.alert(Alert::USER_PROGRAM_STOPPED);
        k.display_text(&format!("program stopped in {}: {why}", hook.name()), true);
        k.stop_lower_loop();
        Flow::STOP
    }

    fn flow_hook(&mut self, k: &mut Api, hook: Hook) -> Flow {
        self.call(k, hook, &[], |f, store| {
            f.typed::<(), i32>(&*store)?.call(store, ()).map(Some)
        })
    }
}

impl UserProgram for WasmProgram {
    fn name(&self) -> &'static str {
        "wasm module"
    }
    fn init(&mut self, k: &mut Api) -> Flow {
        self.flow_hook(k, Hook::Init)
    }
    fn user(&mut self, k: &mut Api) -> Flow {
        self.flow_hook(k, Hook::User)
    }
    fn user_commands(&self) -> &[(u8, u8)] {
        &self.store.data().commands
    }
    fn rs(&mut self, k: &mut Api, cmd: u8, params: &[u8]) {
        let n = params.len() as i32;
        self.call(k, Hook::Rs, params, |f, store| {
            f.typed::<(i32, i32), ()>(&*store)?
                .call(store, (i32::from(cmd), n))
                .map(|()| None)
        });
    }
    fn pic(&mut self, k: &mut Api, event: PicEvent) -> Flow {
        let [e, d] = event.encode();
        self.call(k, Hook::Pic, &[], |f, store| {
            f.typed::<(i32, i32), i32>(&*store)?
                .call(store, (i32::from(e), i32::from(d)))
                .map(Some)
        })
    }
    fn timers(&self) -> [bool; 2] {
        [self.has(Hook::Timer1), self.has(Hook::Timer2)]
    }
    fn timer(&mut self, k: &mut Api, timer: u8) -> Flow {
        let hook = if timer == 2 {
            Hook::Timer2
        } else {
            Hook::Timer1
        };
        self.flow_hook(k, hook)
    }
    fn ad(&mut self, k: &mut Api) -> Flow {
        self.flow_hook(k, Hook::Ad)
    }
    fn fread(&mut self, k: &mut Api, file: u8, data: &[u8]) {
        let n = data.len() as i32;
        self.call(k, Hook::Fread, data, |f, store| {
            f.typed::<(i32, i32), ()>(&*store)?
                .call(store, (i32::from(file), n))
                .map(|()| None)
        });
    }
    fn fin(&mut self, k: &mut Api) {
        self.call(k, Hook::Fin, &[], |f, store| {
            f.typed::<(), ()>(&*store)?.call(store, ()).map(|()| None)
        });
    }
}
