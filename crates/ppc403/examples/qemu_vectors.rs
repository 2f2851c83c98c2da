//! Makes test vectors of the PowerPC 403 core with QEMU's user-mode emulator `qemu-ppc`, or
//! checks a fresh random sample of cases against the core.
//!
//! ```sh
//! # the committed vectors: COUNT cases from seeds BASE.., one line each
//! cargo run --release -p buslab-ppc403 --example qemu_vectors -- generate 4000 crates/ppc403/tests/data/qemu_vectors.txt
//! # COUNT random cases run in qemu-ppc and in the core, compared; exit 1 on a difference
//! cargo run --release -p buslab-ppc403 --example qemu_vectors -- compare 2000 [BASE_SEED]
//! ```
//!
//! A case is a random machine state and 1–8 random user-level integer instructions (see
//! `tests/qemu_cases/mod.rs` for the state and the line format). The generator keeps every
//! case architecturally defined: load and store addresses inside the scratch area and
//! aligned, no invalid forms (an update load with rA = rD or rA = 0, `lmw`/`lswi`/`lswx`
//! loading their own address registers), no division by zero or 0x8000_0000 / -1, no `lswx`
//! with a zero byte count, `stwcx.` only without a reservation or on the address of the
//! `lwarx` before it with no store in between, `tw`/`twi` only on conditions that do not
//! hold, XER only with its defined bits. Every case ends: branches go forward inside the case,
//! `bclr`/`bcctr` only while LR/CTR still hold the target the generator put there, except two
//! shapes that go back: a loop (`bc` decrementing CTR, set to 1..5, back over instructions
//! that may run again) and a detour (`b` forward over straight code, `b` back into it, which
//! ends in a `b` past the first).
//!
//! Many cases go into one program (BATCH), linked below 0x8000 so that the absolute branches
//! and the rA = 0 addressing reach the code and the scratch area: for each case the driver
//! copies the case's state into fixed slots and its bytes into the scratch area, loads every
//! register from the slots, and branches to the case's block; the block restores CTR and r0,
//! runs the instructions, and branches to the epilogue, which stores every register and
//! copies them with the scratch area into the output table. At the end the program writes
//! the table to stdout and exits.

#[path = "../tests/qemu_cases/mod.rs"]
mod cases;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use std::process::{Command, ExitCode, Stdio};

use cases::*;

/// Cases in one program: amortises qemu's start.
const BATCH: usize = 200;
/// The first case's block; blocks are BLOCK bytes apart.
const BLOCKS: u32 = 0x2000;
const BLOCK: u32 = 64;
/// Words before a case's first instruction in its block (restore CTR and r0).
const ENTRY_WORDS: u32 = 3;
/// The driver's fixed slots: the state in (37 words: r0..r31, cr, xer, lr, ctr, block entry),
/// the state out (36 words), the driver's own variables.
const SLOTS_IN: u32 = 0x6000;
const SLOTS_OUT: u32 = 0x6100;
const VARS: u32 = 0x6200;
/// A case's record in the input and output tables.
const RECORD: usize = 512;
const STATE_WORDS: usize = 36;
const CPU: &str = "405";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        ["generate", count, out] => parse(count).and_then(|n| generate(n, 0, Path::new(out))),
        ["generate", count, out, base] => parse(count)
            .and_then(|n| parse(base).and_then(|base| generate(n, base, Path::new(out)))),
        ["compare", count] => parse(count).and_then(|n| compare(n, random_seed())),
        ["compare", count, seed] => {
            parse(count).and_then(|n| parse(seed).and_then(|seed| compare(n, seed)))
        }
        _ => Err(
            "usage: qemu_vectors generate COUNT FILE [BASE_SEED] | compare COUNT [BASE_SEED]"
                .into(),
        ),
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("qemu_vectors: {e}");
            ExitCode::from(2)
        }
    }
}

fn parse<T: std::str::FromStr>(s: &str) -> Result<T, String> {
    s.parse()
        .map_err(|_| format!("{s:?} is not a number (a count or seed is expected)"))
}

fn random_seed() -> u64 {
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0);
    t ^ (u64::from(std::process::id()) << 32)
}

/// Case `k` of a run: its seed and its place in its batch's program.
fn make_cases(count: usize, seed_of: impl Fn(usize) -> u64) -> Vec<Case> {
    (0..count)
        .map(|k| {
            let addr = BLOCKS + BLOCK * (k % BATCH) as u32 + 4 * ENTRY_WORDS;
            generate_case(seed_of(k), addr)
        })
        .collect()
}

fn generate(count: usize, base: u64, out: &Path) -> Result<bool, String> {
    let cases = make_cases(count, |k| base + k as u64);
    let after = run_qemu(&cases)?;
    let mut text = format!(
        "# Vectors of buslab's PowerPC 403 core, made with {} (-cpu {CPU}) by\n\
         # `cargo run --release -p buslab-ppc403 --example qemu_vectors -- generate {count} FILE {base}`.\n\
         # A line: SEED ADDR CODE... | in (the state before: tests/qemu_cases/mod.rs's fill(SEED)\n\
         # with these changes) | out (what the code changed: rN, cr, xer, lr, ctr, mADDR=bytes).\n",
        qemu_version()?
    );
    let mut tally: BTreeMap<String, usize> = BTreeMap::new();
    for (case, after) in cases.into_iter().zip(after) {
        for (i, &w) in case.code.iter().enumerate() {
            *tally
                .entry(disassemble(w, case.addr + 4 * i as u32).0)
                .or_default() += 1;
        }
        writeln!(text, "{}", Vector { case, after }.line()).unwrap();
    }
    let tmp = out.with_extension(format!("tmp.{}", std::process::id()));
    std::fs::write(&tmp, &text).map_err(|e| format!("cannot write {}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, out).map_err(|e| format!("cannot rename to {}: {e}", out.display()))?;
    println!(
        "{count} vectors in {}; instructions by mnemonic:",
        out.display()
    );
    print_tally(&tally);
    Ok(true)
}

fn print_tally(tally: &BTreeMap<String, usize>) {
    let mut line = String::new();
    for (i, (m, n)) in tally.iter().enumerate() {
        write!(line, "{m:>8} {n:<5}").unwrap();
        if i % 8 == 7 {
            println!("{}", line.trim_end());
            line.clear();
        }
    }
    if !line.is_empty() {
        println!("{}", line.trim_end());
    }
    let missing: Vec<String> = all_mnemonics()
        .into_iter()
        .filter(|m| !tally.contains_key(m))
        .collect();
    println!(
        "{} mnemonics; not made: {}",
        tally.len(),
        if missing.is_empty() {
            "none".to_string()
        } else {
            missing.join(" ")
        }
    );
}

fn compare(count: usize, base: u64) -> Result<bool, String> {
    let mut seeds = Rng::new(base);
    let seeds: Vec<u64> = (0..count).map(|_| seeds.next()).collect();
    let cases = make_cases(count, |k| seeds[k]);
    let after = run_qemu(&cases)?;
    let mut differ = 0;
    let mut mnemonics = BTreeMap::<String, (usize, usize)>::new();
    for (case, after) in cases.into_iter().zip(after) {
        let v = Vector { case, after };
        let result = check(&v);
        for (i, &w) in v.case.code.iter().enumerate() {
            let e = mnemonics
                .entry(disassemble(w, v.case.addr + 4 * i as u32).0)
                .or_default();
            e.0 += 1;
            e.1 += usize::from(result.is_err());
        }
        if let Err(e) = result {
            differ += 1;
            if differ <= 20 {
                println!("DIFFERENT {e}\n  vector: {}", v.line());
            }
        }
    }
    if differ > 0 {
        let suspects: Vec<String> = mnemonics
            .iter()
            .filter(|(_, (_, bad))| *bad > 0)
            .map(|(m, (all, bad))| format!("{m} {bad}/{all}"))
            .collect();
        println!(
            "mnemonics in differing cases (differing/all): {}",
            suspects.join(", ")
        );
    }
    println!(
        "ppc403 vs qemu-ppc: {}/{count} cases agree ({} mnemonics, base seed {base}, qemu-ppc -cpu {CPU})",
        count - differ,
        mnemonics.len()
    );
    Ok(differ == 0)
}

fn qemu_version() -> Result<String, String> {
    let out = Command::new("qemu-ppc")
        .arg("--version")
        .output()
        .map_err(|e| format!("cannot run qemu-ppc (Debian package qemu-user): {e}"))?;
    let text = String::from_utf8_lossy(&out.stdout);
    Ok(text.lines().next().unwrap_or("qemu-ppc").trim().to_string())
}

// ---- the generator ----

/// The instruction forms, each one mnemonic of [`all_mnemonics`].
#[derive(Clone, Copy, Debug)]
enum Form {
    Arith(usize, bool, bool),
    DArith(usize),
    DLogic(usize),
    XLogic(usize, bool),
    XUnary(usize, bool),
    Srawi(bool),
    Rotate(u32, bool),
    Cmp(bool),
    CmpImm(bool),
    CrLogic(usize),
    Mcrf,
    Mcrxr,
    Mtcrf,
    Mfcr,
    Mfspr(u32),
    Mtspr(u32),
    DMem(usize),
    XMem(usize),
    Lmw,
    Stmw,
    Lswi,
    Stswi,
    Lswx,
    Stswx,
    Lwarx,
    Stwcx,
    Cache(u32),
    Trap(bool),
    Branch {
        aa: bool,
        lk: bool,
    },
    Bc {
        aa: bool,
        lk: bool,
    },
    Bclr(bool),
    Bcctr(bool),
    /// `bc` back to an earlier instruction with CTR counting the passes (a loop).
    Loop(bool),
    Sync,
    Isync,
    Eieio,
}

fn all_forms() -> Vec<Form> {
    use Form::*;
    let mut v = Vec::new();
    for (i, f) in XO_ARITH.iter().enumerate() {
        for oe in [false, true].into_iter().filter(|&oe| f.2 || !oe) {
            v.push(Arith(i, oe, false));
            v.push(Arith(i, oe, true));
        }
    }
    v.extend((0..D_ARITH.len()).map(DArith));
    v.extend((0..D_LOGIC.len()).map(DLogic));
    for rc in [false, true] {
        v.extend((0..X_LOGIC.len()).map(|i| XLogic(i, rc)));
        v.extend((0..X_UNARY.len()).map(|i| XUnary(i, rc)));
        v.push(Srawi(rc));
        v.extend([20, 21, 23].map(|p| Rotate(p, rc)));
    }
    v.extend([Cmp(false), Cmp(true), CmpImm(false), CmpImm(true)]);
    v.extend((0..CR_LOGIC.len()).map(CrLogic));
    v.extend([Mcrf, Mcrxr, Mtcrf, Mfcr]);
    for (_, n) in USER_SPRS {
        v.extend([Mfspr(n), Mtspr(n)]);
    }
    v.extend((0..D_MEM.len()).map(DMem));
    v.extend((0..X_MEM.len()).map(XMem));
    v.extend([Lmw, Stmw, Lswi, Stswi, Lswx, Stswx, Lwarx, Stwcx]);
    v.extend(CACHE_OPS.iter().map(|f| Cache(f.1)));
    v.extend([Trap(false), Trap(true)]);
    for aa in [false, true] {
        for lk in [false, true] {
            v.extend([Branch { aa, lk }, Bc { aa, lk }]);
        }
    }
    v.extend([Bclr(false), Bclr(true), Bcctr(false), Bcctr(true)]);
    // Twice: a loop is often impossible (CTR already written).
    v.extend([Loop(false), Loop(true), Loop(false), Loop(true)]);
    v.extend([Sync, Isync, Eieio]);
    v
}

/// What the generator knows while it writes a case: which registers earlier instructions may
/// have written (their value is unknown from then on) and which initial values it has fixed.
struct Gen {
    rng: Rng,
    s: State,
    addr: u32,
    n: usize,
    written: u32,
    pinned: u32,
    lr_written: bool,
    lr_target: Option<usize>,
    ctr_written: bool,
    ctr_target: Option<usize>,
    xer_written: bool,
    count_pinned: bool,
    /// The registers of the last `lwarx`'s address, and whether a store came since.
    reserve: Option<(u32, u32)>,
    stored_since_reserve: bool,
    hot: [u32; 4],
    /// The first of the instructions before the current one that a loop may run again: they
    /// read no register whose value the generator fixed (addresses, divisors) and branch
    /// only forward.
    loop_start: usize,
}

impl Form {
    /// Safe to run more than once (see `Gen::loop_start`).
    fn repeatable(self) -> bool {
        use Form::*;
        match self {
            Arith(i, _, _) => !XO_ARITH[i].0.starts_with("div"),
            DArith(_) | DLogic(_) | XLogic(..) | XUnary(..) | Srawi(_) | Rotate(..) => true,
            Cmp(_) | CmpImm(_) | CrLogic(_) | Mcrf | Mcrxr | Mtcrf | Mfcr | Mfspr(_) => true,
            Mtspr(n) => n == 8,
            Branch { .. } | Bc { .. } | Sync | Isync | Eieio => true,
            _ => false,
        }
    }

    fn branches(self) -> bool {
        use Form::*;
        matches!(
            self,
            Branch { .. } | Bc { .. } | Bclr(_) | Bcctr(_) | Loop(_)
        )
    }
}

fn generate_case(seed: u64, addr: u32) -> Case {
    let forms = all_forms();
    let mut g = Gen {
        rng: Rng::new(seed ^ 0x005E_ED0F_C0DE),
        s: fill(seed),
        addr,
        n: 0,
        written: 0,
        pinned: 0,
        lr_written: false,
        lr_target: None,
        ctr_written: false,
        ctr_target: None,
        xer_written: false,
        count_pinned: false,
        reserve: None,
        stored_since_reserve: false,
        hot: [0; 4],
        loop_start: 0,
    };
    g.hot = std::array::from_fn(|_| g.rng.below(32));
    g.n = g.rng.below(MAX_INSNS as u32) as usize + 1;
    let straight: Vec<Form> = forms.iter().copied().filter(|f| !f.branches()).collect();
    let mut code = Vec::with_capacity(g.n);
    while code.len() < g.n {
        if g.n - code.len() >= 3 && g.rng.chance(1, 20) {
            g.detour(&mut code, &straight);
        } else {
            g.one(&mut code, &forms);
        }
    }
    Case {
        seed,
        addr,
        code,
        before: g.s,
    }
}

/// Registers `first`.. for `bytes` bytes of a string load, wrapping from r31 to r0.
fn string_regs(first: u32, bytes: u32) -> u32 {
    (0..bytes.div_ceil(4)).fold(0, |m, k| m | 1 << ((first + k) % 32))
}

impl Gen {
    /// The next instruction, of a form from `forms`.
    fn one(&mut self, code: &mut Vec<u32>, forms: &[Form]) {
        let j = code.len();
        let (form, word) = (0..100)
            .find_map(|_| {
                let form = self.rng.pick(forms);
                self.emit(form, j).map(|w| (form, w))
            })
            .expect("an unconstrained form is always possible");
        if !form.repeatable() {
            self.loop_start = j + 1;
        }
        code.push(word);
    }

    /// A backward `b`: at j a branch forward to t, then (j+1..t-1) straight code ending in a
    /// branch past t, and at t the branch back to j+1. Every path leaves past t.
    fn detour(&mut self, code: &mut Vec<u32>, straight: &[Form]) {
        let j = code.len();
        let t = j + 2 + self.rng.below((self.n - j - 2) as u32) as usize;
        let u = t + 1 + self.rng.below((self.n - t) as u32) as usize;
        let (lk_in, lk_out, lk_back) = (
            self.rng.chance(1, 3),
            self.rng.chance(1, 3),
            self.rng.chance(1, 3),
        );
        let aa_in = self.rng.chance(1, 3);
        let aa_out = self.rng.chance(1, 3);
        // The branch back runs before the straight code: its link is written by then.
        self.lr_written |= lk_in || lk_back;
        code.push(self.b(j, t, aa_in, lk_in));
        while code.len() < t - 1 {
            self.one(code, straight);
        }
        self.lr_written |= lk_out;
        code.push(self.b(t - 1, u, aa_out, lk_out));
        code.push(self.b(t, j + 1, false, lk_back));
        self.loop_start = t + 1;
    }

    /// `b` from instruction `from` to `to`.
    fn b(&self, from: usize, to: usize, aa: bool, lk: bool) -> u32 {
        let field = if aa {
            self.at(to)
        } else {
            (4 * to as u32).wrapping_sub(4 * from as u32)
        };
        op(18) | (field & 0x03FF_FFFC) | if aa { AA } else { 0 } | if lk { LK } else { 0 }
    }

    /// Any register; half the time one of the case's few hot ones, so that results feed
    /// later instructions.
    fn reg(&mut self) -> u32 {
        if self.rng.chance(1, 2) {
            self.hot[self.rng.below(self.hot.len() as u32) as usize]
        } else {
            self.rng.below(32)
        }
    }

    /// A register no earlier instruction writes and no earlier constraint fixed, outside
    /// `exclude`, r0 only if `r0`.
    fn fresh(&mut self, exclude: u32, r0: bool) -> Option<u32> {
        let free = !(self.written | self.pinned | exclude) & if r0 { !0 } else { !1 };
        if free == 0 {
            return None;
        }
        let k = self.rng.below(free.count_ones());
        let mut m = free;
        for _ in 0..k {
            m &= m - 1;
        }
        Some(m.trailing_zeros())
    }

    fn pin(&mut self, r: u32, value: u32) {
        self.s.gpr[r as usize] = value;
        self.pinned |= 1 << r;
    }

    fn write(&mut self, r: u32) {
        self.written |= 1 << r;
    }

    /// An address for `len` bytes in the scratch area, a multiple of `align`.
    fn ea(&mut self, len: u32, align: u32) -> u32 {
        let slots = (SCRATCH_LEN as u32 - len) / align + 1;
        SCRATCH + align * self.rng.below(slots)
    }

    fn displacement(&mut self) -> u32 {
        match self.rng.below(4) {
            0 => 0,
            1 => self.rng.below(64).wrapping_sub(32),
            _ => self.rng.word() as u16 as i16 as u32,
        }
    }

    /// rA (0 when `r0_literal` allows it now and then) and a displacement reaching `ea`.
    fn d_address(&mut self, ea: u32, r0_literal: bool, exclude: u32) -> Option<(u32, u32)> {
        if r0_literal && self.rng.chance(1, 6) {
            return Some((0, ea));
        }
        let ra = self.fresh(exclude, false)?;
        let disp = self.displacement();
        self.pin(ra, ea.wrapping_sub(disp));
        Some((ra, disp))
    }

    /// rA (0 now and then when `r0_literal`) and rB reaching `ea`.
    fn x_address(&mut self, ea: u32, r0_literal: bool, exclude: u32) -> Option<(u32, u32)> {
        if r0_literal && exclude & 1 == 0 && self.rng.chance(1, 6) {
            let rb = self.fresh(exclude, true)?;
            self.pin(rb, ea);
            return Some((0, rb));
        }
        let ra = self.fresh(exclude, false)?;
        let rb = self.fresh(exclude | 1 << ra, true)?;
        let base = match self.rng.below(3) {
            0 => SCRATCH,
            1 => interesting(&mut self.rng),
            _ => self.rng.word(),
        };
        self.pin(ra, base);
        self.pin(rb, ea.wrapping_sub(base));
        Some((ra, rb))
    }

    /// A branch target ahead of instruction `j`: its index (n is the case's end).
    fn target(&mut self, j: usize) -> usize {
        j + 1 + self.rng.below((self.n - j) as u32) as usize
    }

    fn at(&self, index: usize) -> u32 {
        self.addr + 4 * index as u32
    }

    fn bo(&mut self) -> u32 {
        let bo = self.rng.pick(&BO_ALL);
        if bo & 4 == 0 {
            self.ctr_written = true;
        }
        bo
    }

    fn emit(&mut self, form: Form, j: usize) -> Option<u32> {
        use Form::*;
        let rc = |on: bool| if on { RC } else { 0 };
        Some(match form {
            Arith(i, oe, dot) => {
                let (_, xo, _, has_rb) = XO_ARITH[i];
                let rd = self.reg();
                let (ra, rb) = if XO_ARITH[i].0.starts_with("div") {
                    self.division_operands(XO_ARITH[i].0 == "divw")?
                } else {
                    (self.reg(), if has_rb { self.reg() } else { 0 })
                };
                self.write(rd);
                x(xo) | d(rd) | a(ra) | b(rb) | if oe { OE } else { 0 } | rc(dot)
            }
            DArith(i) => {
                let (rd, ra) = (self.reg(), self.reg());
                self.write(rd);
                op(D_ARITH[i].1) | d(rd) | a(ra) | (interesting(&mut self.rng) & 0xFFFF)
            }
            DLogic(i) => {
                let (rs, ra) = (self.reg(), self.reg());
                self.write(ra);
                op(D_LOGIC[i].1) | d(rs) | a(ra) | (interesting(&mut self.rng) & 0xFFFF)
            }
            XLogic(i, dot) => {
                let (rs, ra, rb) = (self.reg(), self.reg(), self.reg());
                self.write(ra);
                x(X_LOGIC[i].1) | d(rs) | a(ra) | b(rb) | rc(dot)
            }
            XUnary(i, dot) => {
                let (rs, ra) = (self.reg(), self.reg());
                self.write(ra);
                x(X_UNARY[i].1) | d(rs) | a(ra) | rc(dot)
            }
            Srawi(dot) => {
                let (rs, ra, sh) = (self.reg(), self.reg(), self.reg());
                self.write(ra);
                x(824) | d(rs) | a(ra) | b(sh) | rc(dot)
            }
            Rotate(primary, dot) => {
                let (rs, ra, sh, mb, me) =
                    (self.reg(), self.reg(), self.reg(), self.reg(), self.reg());
                self.write(ra);
                op(primary) | d(rs) | a(ra) | b(sh) | mb << 6 | me << 1 | rc(dot)
            }
            Cmp(logical) => {
                let crf = self.rng.below(8);
                x(if logical { 32 } else { 0 }) | crf << 23 | a(self.reg()) | b(self.reg())
            }
            CmpImm(logical) => {
                let crf = self.rng.below(8);
                op(if logical { 10 } else { 11 })
                    | crf << 23
                    | a(self.reg())
                    | (interesting(&mut self.rng) & 0xFFFF)
            }
            CrLogic(i) => {
                op(19) | CR_LOGIC[i].1 << 1 | d(self.reg()) | a(self.reg()) | b(self.reg())
            }
            Mcrf => op(19) | self.rng.below(8) << 23 | self.rng.below(8) << 18,
            Mcrxr => x(512) | self.rng.below(8) << 23,
            Mtcrf => {
                let crm = match self.rng.below(4) {
                    0 => 0xFF,
                    _ => self.rng.below(256),
                };
                x(144) | d(self.reg()) | crm << 12
            }
            Mfcr => {
                let rd = self.reg();
                self.write(rd);
                x(19) | d(rd)
            }
            Mfspr(n) => {
                let rd = self.reg();
                self.write(rd);
                x(339) | d(rd) | spr(n)
            }
            Mtspr(n) => {
                let rs = match n {
                    1 => {
                        // Only XER's defined bits: the reserved ones read back differently.
                        let rs = self.fresh(0, true)?;
                        let v = interesting(&mut self.rng) & XER_DEFINED;
                        self.pin(rs, v);
                        self.xer_written = true;
                        rs
                    }
                    8 => {
                        self.lr_written = true;
                        self.reg()
                    }
                    _ => {
                        self.ctr_written = true;
                        self.reg()
                    }
                };
                x(467) | d(rs) | spr(n)
            }
            DMem(i) => {
                let (_, primary, size, update, store) = D_MEM[i];
                let rs = self.reg();
                let ea = self.ea(size, size);
                let exclude = if update && !store { 1 << rs } else { 0 };
                let (ra, disp) = self.d_address(ea, !update, exclude)?;
                self.memory_effects(rs, ra, update, store);
                op(primary) | d(rs) | a(ra) | (disp & 0xFFFF)
            }
            XMem(i) => {
                let (_, xo, size, update, store) = X_MEM[i];
                let rs = self.reg();
                let ea = self.ea(size, size);
                let exclude = if update && !store { 1 << rs } else { 0 };
                let (ra, rb) = self.x_address(ea, !update, exclude)?;
                self.memory_effects(rs, ra, update, store);
                x(xo) | d(rs) | a(ra) | b(rb)
            }
            Lmw => {
                let rd = self.multiple_first(false);
                let regs = !0u32 << rd;
                let ea = self.ea(4 * (32 - rd), 4);
                let (ra, disp) = self.d_address(ea, true, regs)?;
                self.written |= regs;
                op(46) | d(rd) | a(ra) | (disp & 0xFFFF)
            }
            Stmw => {
                let rs = self.multiple_first(true);
                let ea = self.ea(4 * (32 - rs), 4);
                let (ra, disp) = self.d_address(ea, true, 0)?;
                self.stored();
                op(47) | d(rs) | a(ra) | (disp & 0xFFFF)
            }
            Lswi | Stswi => {
                let nb = self.rng.below(32) + 1;
                let rd = self.reg();
                let load = matches!(form, Lswi);
                let regs = if load { string_regs(rd, nb) } else { 0 };
                let ra = self.fresh(regs, false)?;
                let ea = self.ea(nb, 1);
                self.pin(ra, ea);
                if load {
                    self.written |= regs;
                } else {
                    self.stored();
                }
                x(if load { 597 } else { 725 }) | d(rd) | a(ra) | b(nb % 32)
            }
            Lswx | Stswx => {
                if self.xer_written {
                    return None;
                }
                if !self.count_pinned {
                    // Mostly a few registers' worth, sometimes up to XER's 127 bytes.
                    let count = if self.rng.chance(1, 4) {
                        self.rng.below(127) + 1
                    } else {
                        self.rng.below(32) + 1
                    };
                    self.s.xer = self.s.xer & !0x7F | count;
                    self.count_pinned = true;
                }
                let count = self.s.xer & 0x7F;
                let rd = self.reg();
                let load = matches!(form, Lswx);
                let regs = if load { string_regs(rd, count) } else { 0 };
                let ea = self.ea(count, 1);
                let (ra, rb) = self.x_address(ea, true, regs)?;
                if load {
                    self.written |= regs;
                } else {
                    self.stored();
                }
                x(if load { 533 } else { 661 }) | d(rd) | a(ra) | b(rb)
            }
            Lwarx => {
                let rd = self.reg();
                let ea = self.ea(4, 4);
                let (ra, rb) = self.x_address(ea, true, 0)?;
                self.write(rd);
                self.reserve = Some((ra, rb));
                self.stored_since_reserve = false;
                x(20) | d(rd) | a(ra) | b(rb)
            }
            Stwcx => {
                let rs = self.reg();
                let (ra, rb) = match self.reserve {
                    None => {
                        let ea = self.ea(4, 4);
                        self.x_address(ea, true, 0)?
                    }
                    Some((ra, rb)) => {
                        let written = self.written & (1 << ra | 1 << rb) & !1 != 0
                            || rb == 0 && self.written & 1 != 0;
                        if self.stored_since_reserve || written {
                            return None;
                        }
                        (ra, rb)
                    }
                };
                self.stored();
                x(150) | d(rs) | a(ra) | b(rb) | RC
            }
            Cache(xo) => {
                let ea = self.ea(1, 1);
                let (ra, rb) = self.x_address(ea, true, 0)?;
                x(xo) | a(ra) | b(rb)
            }
            Trap(immediate) => {
                // Operands the generator knows, and only the conditions that do not hold
                // (a trap ends the case in a signal).
                let ra = self.fresh(0, true)?;
                let va = interesting(&mut self.rng);
                self.pin(ra, va);
                let (rb, vb) = if immediate {
                    let imm = interesting(&mut self.rng) & 0xFFFF;
                    (imm, imm as u16 as i16 as u32)
                } else {
                    let rb = self.fresh(1 << ra, true)?;
                    let vb = interesting(&mut self.rng);
                    self.pin(rb, vb);
                    (rb, vb)
                };
                let (sa, sb) = (va as i32, vb as i32);
                let fires = [sa < sb, sa > sb, va == vb, va < vb, va > vb]
                    .iter()
                    .fold(0, |m, &c| m << 1 | u32::from(c));
                let to = self.rng.below(32) & !fires;
                if immediate {
                    op(3) | d(to) | a(ra) | rb
                } else {
                    x(4) | d(to) | a(ra) | b(rb)
                }
            }
            Branch { aa, lk } => {
                let t = self.target(j);
                if lk {
                    self.lr_written = true;
                }
                let field = if aa { self.at(t) } else { 4 * (t - j) as u32 };
                op(18) | (field & 0x03FF_FFFC) | if aa { AA } else { 0 } | if lk { LK } else { 0 }
            }
            Bc { aa, lk } => {
                let t = self.target(j);
                let (bo, bi) = (self.bo(), self.reg());
                if lk {
                    self.lr_written = true;
                }
                let field = if aa { self.at(t) } else { 4 * (t - j) as u32 };
                op(16)
                    | d(bo)
                    | a(bi)
                    | (field & 0xFFFC)
                    | if aa { AA } else { 0 }
                    | if lk { LK } else { 0 }
            }
            Bclr(lk) => {
                if self.lr_written || self.lr_target.is_some_and(|t| t <= j) {
                    return None;
                }
                if self.lr_target.is_none() {
                    let t = self.target(j);
                    self.s.lr = self.at(t) | self.rng.below(4);
                    self.lr_target = Some(t);
                }
                let (bo, bi) = (self.bo(), self.reg());
                if lk {
                    self.lr_written = true;
                }
                op(19) | d(bo) | a(bi) | 16 << 1 | if lk { LK } else { 0 }
            }
            Bcctr(lk) => {
                if self.ctr_written || self.ctr_target.is_some_and(|t| t <= j) {
                    return None;
                }
                if self.ctr_target.is_none() {
                    let t = self.target(j);
                    self.s.ctr = self.at(t) | self.rng.below(4);
                    self.ctr_target = Some(t);
                }
                // BO without "decrement CTR": that form of bcctr is invalid.
                let bo = self.rng.pick(&[4, 5, 12, 13, 20]);
                let bi = self.reg();
                if lk {
                    self.lr_written = true;
                }
                op(19) | d(bo) | a(bi) | 528 << 1 | if lk { LK } else { 0 }
            }
            Loop(lk) => {
                if self.ctr_written || self.ctr_target.is_some() {
                    return None;
                }
                let k = self.loop_start + self.rng.below((j - self.loop_start + 1) as u32) as usize;
                self.s.ctr = self.rng.below(5) + 1;
                self.ctr_written = true;
                // Decrement CTR and branch while it is not zero (and the condition holds).
                let bo = self.rng.pick(&[0, 1, 8, 9, 16, 17]);
                let bi = self.reg();
                if lk {
                    self.lr_written = true;
                }
                let disp = (4 * k as u32).wrapping_sub(4 * j as u32);
                op(16) | d(bo) | a(bi) | (disp & 0xFFFC) | if lk { LK } else { 0 }
            }
            Sync => x(598),
            Isync => op(19) | 150 << 1,
            Eieio => x(854),
        })
    }

    /// Dividend and divisor registers with a defined quotient.
    fn division_operands(&mut self, signed: bool) -> Option<(u32, u32)> {
        let ra = self.fresh(0, true)?;
        if self.rng.chance(1, 8) {
            let v = loop {
                let v = interesting(&mut self.rng);
                if v != 0 {
                    break v;
                }
            };
            self.pin(ra, v);
            return Some((ra, ra));
        }
        let rb = self.fresh(1 << ra, true)?;
        let dividend = interesting(&mut self.rng);
        let divisor = loop {
            let v = interesting(&mut self.rng);
            if v != 0 && !(signed && dividend == 0x8000_0000 && v == 0xFFFF_FFFF) {
                break v;
            }
        };
        self.pin(ra, dividend);
        self.pin(rb, divisor);
        Some((ra, rb))
    }

    /// The first register of `lmw`/`stmw`: mostly a few registers, sometimes many (lmw
    /// never from r0: its rA would be in the range).
    fn multiple_first(&mut self, r0: bool) -> u32 {
        if self.rng.chance(2, 3) {
            32 - (self.rng.below(8) + 1)
        } else if r0 {
            self.rng.below(32)
        } else {
            self.rng.below(31) + 1
        }
    }

    fn memory_effects(&mut self, rs: u32, ra: u32, update: bool, store: bool) {
        if store {
            self.stored();
        } else {
            self.write(rs);
        }
        if update {
            self.write(ra);
        }
    }

    fn stored(&mut self) {
        self.stored_since_reserve = true;
    }
}

// ---- running cases in qemu-ppc ----

/// Runs every case in qemu-ppc; the state after each.
fn run_qemu(cases: &[Case]) -> Result<Vec<State>, String> {
    for tool in ["qemu-ppc", "powerpc-linux-gnu-as", "powerpc-linux-gnu-ld"] {
        if Command::new(tool).arg("--version").output().is_err() {
            return Err(format!(
                "{tool} is missing (Debian qemu-user, binutils-powerpc-linux-gnu; \
                 scripts/setup-test-deps.sh installs them)"
            ));
        }
    }
    let dir = std::env::temp_dir().join(format!("qemu_vectors.{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let result = cases
        .chunks(BATCH)
        .enumerate()
        .map(|(i, batch)| run_batch(&dir, i, batch))
        .collect::<Result<Vec<_>, _>>();
    let _ = std::fs::remove_dir_all(&dir);
    Ok(result?.into_iter().flatten().collect())
}

fn run_batch(dir: &Path, index: usize, batch: &[Case]) -> Result<Vec<State>, String> {
    let src = dir.join(format!("batch{index}.s"));
    let obj = src.with_extension("o");
    let elf = src.with_extension("elf");
    std::fs::write(&src, program(batch)).map_err(|e| format!("{}: {e}", src.display()))?;
    tool(
        Command::new("powerpc-linux-gnu-as")
            .arg("-mregnames")
            .arg("-o")
            .arg(&obj)
            .arg(&src),
    )?;
    tool(
        Command::new("powerpc-linux-gnu-ld")
            .args(["-nostdlib", "-static", "-Ttext=0x1000"])
            .arg(format!("--section-start=.cases=0x{BLOCKS:x}"))
            .arg(format!("--section-start=.slots=0x{SLOTS_IN:x}"))
            .arg(format!("--section-start=.scratch=0x{SCRATCH:x}"))
            .args(["-Tdata=0x10000", "-o"])
            .arg(&elf)
            .arg(&obj),
    )?;
    let out = tool(Command::new("qemu-ppc").args(["-cpu", CPU]).arg(&elf))?;
    if out.len() != batch.len() * RECORD {
        return Err(format!(
            "qemu-ppc wrote {} bytes for {} cases, not {}",
            out.len(),
            batch.len(),
            batch.len() * RECORD
        ));
    }
    Ok(out
        .chunks(RECORD)
        .map(|r| {
            let w = |k: usize| u32::from_be_bytes(r[4 * k..4 * k + 4].try_into().unwrap());
            let s = 4 * STATE_WORDS;
            State {
                gpr: std::array::from_fn(w),
                cr: w(32),
                xer: w(33) & XER_DEFINED,
                lr: w(34),
                ctr: w(35),
                scratch: r[s..s + SCRATCH_LEN].try_into().unwrap(),
            }
        })
        .collect())
}

/// Runs a tool; its stdout, or an error with its stderr.
fn tool(cmd: &mut Command) -> Result<Vec<u8>, String> {
    let out = cmd
        .stdin(Stdio::null())
        .output()
        .map_err(|e| format!("cannot run {cmd:?}: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "{cmd:?} failed ({}): {}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    Ok(out.stdout)
}

/// The assembly program running `batch` (see the module's comment).
fn program(batch: &[Case]) -> String {
    let n = batch.len();
    let (pin, pout, left, dummy) = (VARS, VARS + 4, VARS + 8, VARS + 12);
    let mut s = String::new();
    writeln!(
        s,
        "    .section .text
    .globl _start
_start:
    lis r3, table_in@ha
    addi r3, r3, table_in@l
    stw r3, {pin}(0)
    lis r3, table_out@ha
    addi r3, r3, table_out@l
    stw r3, {pout}(0)
    li r3, {n}
    stw r3, {left}(0)
next:
    lwz r3, {pin}(0)
    li r4, 37
    mtctr r4
    addi r5, r3, -4
    li r6, {}
1:  lwzu r7, 4(r5)
    stwu r7, 4(r6)
    bdnz 1b
    li r4, {}
    mtctr r4
    addi r5, r3, {}
    li r6, {}
2:  lwzu r7, 4(r5)
    stwu r7, 4(r6)
    bdnz 2b
    li r6, {dummy}
    stwcx. r7, 0, r6          # no reservation left from the case before
    lwz r0, {}(0)
    mtlr r0
    lwz r0, {}(0)
    mtcrf 0xff, r0
    lwz r0, {}(0)
    mtxer r0
    lwz r0, {}(0)
    mtctr r0",
        SLOTS_IN - 4,
        SCRATCH_LEN / 4,
        4 * 37 - 4,
        SCRATCH - 4,
        SLOTS_IN + 4 * 34,
        SLOTS_IN + 4 * 32,
        SLOTS_IN + 4 * 33,
        SLOTS_IN + 4 * 36,
    )
    .unwrap();
    for r in 1..32 {
        writeln!(s, "    lwz r{r}, {}(0)", SLOTS_IN + 4 * r).unwrap();
    }
    writeln!(s, "    bctr\nepilogue:").unwrap();
    for r in 0..32 {
        writeln!(s, "    stw r{r}, {}(0)", SLOTS_OUT + 4 * r).unwrap();
    }
    writeln!(
        s,
        "    mfcr r0
    stw r0, {}(0)
    mfxer r0
    stw r0, {}(0)
    mflr r0
    stw r0, {}(0)
    mfctr r0
    stw r0, {}(0)
    lwz r6, {pout}(0)
    addi r6, r6, -4
    li r4, {STATE_WORDS}
    mtctr r4
    li r5, {}
3:  lwzu r7, 4(r5)
    stwu r7, 4(r6)
    bdnz 3b
    li r4, {}
    mtctr r4
    li r5, {}
4:  lwzu r7, 4(r5)
    stwu r7, 4(r6)
    bdnz 4b
    lwz r3, {pin}(0)
    addi r3, r3, {RECORD}
    stw r3, {pin}(0)
    lwz r3, {pout}(0)
    addi r3, r3, {RECORD}
    stw r3, {pout}(0)
    lwz r3, {left}(0)
    addic. r3, r3, -1
    stw r3, {left}(0)
    bne next
    li r0, 4                  # write(1, table_out, size)
    li r3, 1
    lis r4, table_out@ha
    addi r4, r4, table_out@l
    lis r5, {}
    ori r5, r5, {}
    sc
    li r0, 1                  # exit(0)
    li r3, 0
    sc",
        SLOTS_OUT + 4 * 32,
        SLOTS_OUT + 4 * 33,
        SLOTS_OUT + 4 * 34,
        SLOTS_OUT + 4 * 35,
        SLOTS_OUT - 4,
        SCRATCH_LEN / 4,
        SCRATCH - 4,
        (n * RECORD) >> 16,
        (n * RECORD) & 0xFFFF,
    )
    .unwrap();
    writeln!(s, "    .section .cases,\"ax\"").unwrap();
    for (i, c) in batch.iter().enumerate() {
        let entry = BLOCKS + BLOCK * i as u32;
        assert_eq!(
            c.addr,
            entry + 4 * ENTRY_WORDS,
            "case {i} is not at its block"
        );
        writeln!(
            s,
            "    .balign {BLOCK}\ncase{i}:\n    lwz r0, {}(0)\n    mtctr r0\n    lwz r0, {SLOTS_IN}(0)",
            SLOTS_IN + 4 * 35
        )
        .unwrap();
        for w in &c.code {
            writeln!(s, "    .long 0x{w:08x}").unwrap();
        }
        writeln!(s, "    b epilogue").unwrap();
    }
    writeln!(
        s,
        "    .section .slots,\"aw\",@nobits\n    .space 0x400\n    .section .scratch,\"aw\",@nobits\n    .space {SCRATCH_LEN}\n    .data\n    .balign {RECORD}\ntable_in:"
    )
    .unwrap();
    for (i, c) in batch.iter().enumerate() {
        let st = &c.before;
        let mut words: Vec<u32> = st.gpr.to_vec();
        words.extend([st.cr, st.xer, st.lr, st.ctr, BLOCKS + BLOCK * i as u32]);
        for chunk in words.chunks(8) {
            let list: Vec<String> = chunk.iter().map(|w| format!("0x{w:08x}")).collect();
            writeln!(s, "    .long {}", list.join(",")).unwrap();
        }
        for chunk in st.scratch.chunks(16) {
            let list: Vec<String> = chunk.iter().map(|b| format!("0x{b:02x}")).collect();
            writeln!(s, "    .byte {}", list.join(",")).unwrap();
        }
        writeln!(s, "    .balign {RECORD}").unwrap();
    }
    writeln!(
        s,
        "    .bss\n    .balign {RECORD}\ntable_out:\n    .space {}",
        n * RECORD
    )
    .unwrap();
    s
}
