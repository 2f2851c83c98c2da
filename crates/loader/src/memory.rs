//! The PowerPC node's memory: its map (what the loader may write) and its image (what it
//! holds, kept in the node's state file).
//!
//! The map follows the seed (002 §4.4.2.3): programs are linked into RAM (the example at
//! 0x30000, interrupt handlers 0x30000..0x32000, code from 0x32000), the loader and the boot
//! code sit in flash at the top of the address space (0xFFFE2000, the reset vector at
//! 0xFFFFFFFC). The sizes are ours (docs/loader.md): 4 MiB of DRAM from 0, of which the
//! first 128 KiB hold the firmware's own data (exception vectors, MoniCAN's and the loader's
//! variables, the stack) and the upper 2 MiB the S-record text as it arrives (the seed's
//! `debut_fichier`); 128 KiB of flash at 0xFFFE0000 that the loader does not program.

use std::collections::BTreeMap;

use crate::srec::{Problem, Program, SrecErrors};

/// What a region of the map is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Use {
    /// RAM the loader writes programs into.
    Programs,
    /// Memory the loader must not write; the text says what it holds.
    Reserved(&'static str),
}

/// A region of the address space (inclusive bounds).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Region {
    pub start: u32,
    pub end: u32,
    pub name: &'static str,
    pub usage: Use,
}

impl Region {
    pub fn len(&self) -> u64 {
        u64::from(self.end) - u64::from(self.start) + 1
    }

    pub fn is_empty(&self) -> bool {
        false
    }
}

/// Where programs may go.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemoryMap {
    /// In address order, not overlapping.
    regions: Vec<Region>,
}

/// Bytes of the loader's receive buffer (`debut_fichier`): the largest S-record file.
pub const TEXT_BUFFER: usize = 2 * 1024 * 1024;

impl MemoryMap {
    /// The PowerPC node's map (module documentation).
    pub fn ppc403() -> Self {
        Self {
            regions: vec![
                Region {
                    start: 0x0000_0000,
                    end: 0x0001_FFFF,
                    name: "RAM (firmware data)",
                    usage: Use::Reserved(
                        "the firmware's own RAM (exception vectors, variables, stack)",
                    ),
                },
                Region {
                    start: 0x0002_0000,
                    end: 0x001F_FFFF,
                    name: "RAM (programs)",
                    usage: Use::Programs,
                },
                Region {
                    start: 0x0020_0000,
                    end: 0x003F_FFFF,
                    name: "RAM (debut_fichier)",
                    usage: Use::Reserved("the loader's buffer for the S-record text"),
                },
                Region {
                    start: 0xFFFE_0000,
                    end: 0xFFFF_FFFF,
                    name: "flash",
                    usage: Use::Reserved("flash (the loader, MoniCAN and the boot code)"),
                },
            ],
        }
    }

    pub fn regions(&self) -> &[Region] {
        &self.regions
    }

    /// The RAM programs may be written to (the first such region).
    pub fn program_ram(&self) -> Option<Region> {
        self.regions
            .iter()
            .copied()
            .find(|r| r.usage == Use::Programs)
    }

    /// Whether `start..=end` lies in memory the loader writes; `Err` says what it is instead.
    pub fn check(&self, start: u32, end: u32) -> Result<(), String> {
        for r in &self.regions {
            if start > r.end || end < r.start {
                continue;
            }
            return match r.usage {
                Use::Programs if start >= r.start && end <= r.end => Ok(()),
                Use::Programs => Err(format!(
                    "partly outside {} 0x{:08X}..=0x{:08X}",
                    r.name, r.start, r.end
                )),
                Use::Reserved(what) => Err(format!("{what}, not for programs")),
            };
        }
        let loadable = self
            .program_ram()
            .map(|r| format!(": programs go to 0x{:08X}..=0x{:08X}", r.start, r.end))
            .unwrap_or_default();
        Err(format!("not memory of the node{loadable}"))
    }

    /// Every data record of `program` that does not fit the map, and records that overlap.
    pub fn check_program(&self, program: &Program) -> SrecErrors {
        let mut errors = SrecErrors::default();
        for s in &program.segments {
            let Some(end) = s.end() else { continue };
            if let Err(what) = self.check(s.address, end) {
                errors.push(
                    s.line,
                    Problem::Address {
                        start: s.address,
                        end,
                        what,
                    },
                );
            }
        }
        let overlaps = program.overlaps();
        for e in overlaps.errors {
            errors.push(e.line, e.problem);
        }
        errors.more += overlaps.more;
        errors.errors.sort_by_key(|e| e.line);
        errors
    }
}

/// What the node's memory holds: the bytes written by loads (merged runs), and the entry
/// point of the last program loaded. Memory nobody wrote reads as 0.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MemoryImage {
    /// Start address → bytes; runs neither overlap nor touch.
    runs: BTreeMap<u32, Vec<u8>>,
    entry: Option<u32>,
}

impl MemoryImage {
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes `data` at `address` (over what was there).
    pub fn write(&mut self, address: u32, data: &[u8]) {
        if data.is_empty() {
            return;
        }
        let start = u64::from(address);
        let end = start + data.len() as u64; // exclusive
        // Runs that overlap or touch [start, end) are merged into one.
        let touching: Vec<u32> = self
            .runs
            .range(..=end.min(u64::from(u32::MAX)) as u32)
            .filter(|(a, d)| u64::from(**a) + d.len() as u64 >= start && u64::from(**a) <= end)
            .map(|(a, _)| *a)
            .collect();
        let mut merged_start = start;
        let mut merged_end = end;
        for a in &touching {
            let len = self.runs[a].len() as u64;
            merged_start = merged_start.min(u64::from(*a));
            merged_end = merged_end.max(u64::from(*a) + len);
        }
        let mut bytes = vec![0u8; (merged_end - merged_start) as usize];
        for a in touching {
            if let Some(old) = self.runs.remove(&a) {
                let at = (u64::from(a) - merged_start) as usize;
                bytes[at..at + old.len()].copy_from_slice(&old);
            }
        }
        let at = (start - merged_start) as usize;
        bytes[at..at + data.len()].copy_from_slice(data);
        self.runs.insert(merged_start as u32, bytes);
    }

    /// Writes every data record of `program` and takes its entry point.
    pub fn load(&mut self, program: &Program) {
        for s in &program.segments {
            self.write(s.address, &s.data);
        }
        self.entry = program.start;
    }

    /// `len` bytes from `address` (0 where nothing was written).
    pub fn read(&self, address: u32, len: usize) -> Vec<u8> {
        let mut out = vec![0u8; len];
        let start = u64::from(address);
        let end = start + len as u64;
        let first = self
            .runs
            .range(..=address)
            .next_back()
            .map_or(address, |(a, _)| *a);
        for (a, bytes) in self.runs.range(first..) {
            let a = u64::from(*a);
            if a >= end {
                break;
            }
            let from = start.max(a);
            let to = end.min(a + bytes.len() as u64);
            if from < to {
                out[(from - start) as usize..(to - start) as usize]
                    .copy_from_slice(&bytes[(from - a) as usize..(to - a) as usize]);
            }
        }
        out
    }

    /// The written ranges in address order (inclusive bounds).
    pub fn ranges(&self) -> Vec<(u32, u32)> {
        self.runs
            .iter()
            .map(|(a, d)| (*a, a.wrapping_add(d.len() as u32 - 1)))
            .collect()
    }

    /// The written runs.
    pub fn runs(&self) -> impl Iterator<Item = (u32, &[u8])> {
        self.runs.iter().map(|(a, d)| (*a, d.as_slice()))
    }

    /// Bytes written in all.
    pub fn len(&self) -> usize {
        self.runs.values().map(Vec::len).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.runs.is_empty()
    }

    /// The entry point of the last program loaded.
    pub fn entry(&self) -> Option<u32> {
        self.entry
    }

    /// The image as an S-record file (S0 `header`, S3 data, S7 entry point).
    pub fn to_srec(&self, header: &str) -> Vec<u8> {
        crate::srec::write(header.as_bytes(), self.runs(), self.entry)
    }

    /// An image from an S-record file (its data and entry point).
    pub fn from_program(program: &Program) -> Self {
        let mut image = Self::new();
        image.load(program);
        image
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_map_says_where_programs_go() {
        let map = MemoryMap::ppc403();
        assert_eq!(map.check(0x30000, 0x31FFF), Ok(()));
        assert_eq!(
            map.check(0xFFFE2000, 0xFFFE20FF).unwrap_err(),
            "flash (the loader, MoniCAN and the boot code), not for programs"
        );
        assert_eq!(
            map.check(0x1000_0000, 0x1000_0003).unwrap_err(),
            "not memory of the node: programs go to 0x00020000..=0x001FFFFF"
        );
        assert!(
            map.check(0x1FFFF0, 0x200010)
                .unwrap_err()
                .contains("partly outside")
        );
        assert!(map.check(0x100, 0x1FF).unwrap_err().contains("firmware"));
    }

    #[test]
    fn writes_merge_and_read_back() {
        let mut m = MemoryImage::new();
        m.write(0x100, &[1, 2, 3, 4]);
        m.write(0x104, &[5, 6]);
        m.write(0x200, &[9]);
        m.write(0x0FE, &[7, 8, 0xAA]);
        assert_eq!(m.ranges(), [(0xFE, 0x105), (0x200, 0x200)]);
        assert_eq!(m.read(0xFC, 12), [0, 0, 7, 8, 0xAA, 2, 3, 4, 5, 6, 0, 0]);
        assert_eq!(m.read(0x1FF, 3), [0, 9, 0]);
        assert_eq!(m.len(), 9);
        // A write spanning two runs joins them.
        m.write(0x105, &[0x55; 0xFB]);
        assert_eq!(m.ranges(), [(0xFE, 0x200)]);
        assert_eq!(m.read(0x200, 1), [9]);
        let text = m.to_srec("t");
        let back = MemoryImage::from_program(&crate::srec::parse(&text).unwrap());
        assert_eq!(back.runs, m.runs);
        // The top of the address space.
        m.write(0xFFFF_FFFE, &[1, 2]);
        assert_eq!(m.read(0xFFFF_FFFE, 2), [1, 2]);
        assert_eq!(m.ranges().last(), Some(&(0xFFFF_FFFE, 0xFFFF_FFFF)));
    }
}
