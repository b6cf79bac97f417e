//! The board image: the release ELF of `firmware/cortex-m/board` (bin `rspr-board`, the file
//! `build-and-size.sh` measures), its symbols, and the check that it fits the real
//! STM32F405RG (the emulated F427 has more flash and SRAM, so a run proves nothing about the
//! fit).

use std::path::{Path, PathBuf};

/// The STM32F405RG's memories (DS8626 section 3.4, RM0090 rev 19 section 2.3.1):
/// flash, main SRAM (SRAM1 112 KiB + SRAM2 16 KiB, contiguous) and the core-coupled RAM.
pub const FLASH: Region = Region {
    name: "flash",
    base: 0x0800_0000,
    size: 1024 * 1024,
};
/// SRAM1 + SRAM2.
pub const SRAM: Region = Region {
    name: "SRAM",
    base: 0x2000_0000,
    size: 128 * 1024,
};
/// CCM data RAM.
pub const CCM: Region = Region {
    name: "CCM",
    base: 0x1000_0000,
    size: 64 * 1024,
};

/// One memory of the part.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Region {
    /// Name.
    pub name: &'static str,
    /// First address.
    pub base: u64,
    /// Bytes.
    pub size: u64,
}

impl Region {
    fn contains(&self, start: u64, len: u64) -> bool {
        start >= self.base && start.saturating_add(len) <= self.base + self.size
    }
}

/// Why the image could not be read or does not fit.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The file.
    #[error("reading {path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// Not a 32-bit little-endian ELF, or a header points outside the file.
    #[error("{path}: not a readable ELF32 little-endian file ({what})")]
    Elf {
        /// The path.
        path: PathBuf,
        /// What was wrong.
        what: &'static str,
    },
    /// A symbol the emulator needs is missing.
    #[error("{path}: no symbol {name}")]
    NoSymbol {
        /// The path.
        path: PathBuf,
        /// The symbol.
        name: String,
    },
}

/// An allocated section.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Section {
    /// Its name.
    pub name: String,
    /// Run-time address.
    pub addr: u64,
    /// Bytes.
    pub size: u64,
    /// Occupies no file bytes (`.bss`, `.uninit`).
    pub nobits: bool,
}

/// A loadable segment: where its bytes are stored and where they run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Segment {
    /// Load (storage) address.
    pub load_addr: u64,
    /// Run-time address.
    pub run_addr: u64,
    /// Bytes stored.
    pub file_size: u64,
    /// Bytes at run time.
    pub mem_size: u64,
}

/// The firmware ELF.
#[derive(Debug, Clone)]
pub struct Firmware {
    /// Where it was read from.
    pub path: PathBuf,
    /// The file.
    pub bytes: Vec<u8>,
    /// Allocated sections.
    pub sections: Vec<Section>,
    /// Loadable segments.
    pub segments: Vec<Segment>,
    symbols: Vec<(String, u64)>,
}

fn u16_at(b: &[u8], at: usize) -> Option<u64> {
    let s = b.get(at..at + 2)?;
    Some(u64::from(u16::from_le_bytes([s[0], s[1]])))
}

fn u32_at(b: &[u8], at: usize) -> Option<u64> {
    let s = b.get(at..at + 4)?;
    Some(u64::from(u32::from_le_bytes([s[0], s[1], s[2], s[3]])))
}

fn cstr(b: &[u8], at: usize) -> Option<String> {
    let rest = b.get(at..)?;
    let end = rest.iter().position(|c| *c == 0)?;
    Some(String::from_utf8_lossy(rest.get(..end)?).into_owned())
}

const SHF_ALLOC: u64 = 2;
const SHT_NOBITS: u64 = 8;
const SHT_SYMTAB: u64 = 2;
const PT_LOAD: u64 = 1;

/// The environment variable that names the release image (`run.sh` sets it from the
/// Cortex-M workspace's target directory, which honours `CARGO_TARGET_DIR`).
pub const ELF_VARIABLE: &str = "RSPR_BOARD_ELF";

/// The release image: `$RSPR_BOARD_ELF`, or where `firmware/cortex-m/board/build-and-size.sh`
/// puts it without `CARGO_TARGET_DIR`.
pub fn default_path() -> PathBuf {
    match std::env::var_os(ELF_VARIABLE) {
        Some(p) if !p.is_empty() => PathBuf::from(p),
        _ => Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../cortex-m/target/thumbv7em-none-eabihf/release/rspr-board"),
    }
}

impl Firmware {
    /// Reads and parses the ELF at `path`.
    pub fn read(path: &Path) -> Result<Self, ImageError> {
        let bytes = std::fs::read(path).map_err(|source| ImageError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(path, bytes)
    }

    /// Parses an ELF already read.
    pub fn parse(path: &Path, bytes: Vec<u8>) -> Result<Self, ImageError> {
        let bad = |what| ImageError::Elf {
            path: path.to_path_buf(),
            what,
        };
        if bytes.get(..4) != Some(b"\x7fELF".as_slice())
            || bytes.get(4) != Some(&1)
            || bytes.get(5) != Some(&1)
        {
            return Err(bad("magic, class or byte order"));
        }
        let b = &bytes;
        let field = |at: usize, what| u32_at(b, at).ok_or(bad(what));
        let half = |at: usize, what| u16_at(b, at).ok_or(bad(what));
        let phoff = field(28, "e_phoff")? as usize;
        let shoff = field(32, "e_shoff")? as usize;
        let phentsize = half(42, "e_phentsize")? as usize;
        let phnum = half(44, "e_phnum")? as usize;
        let shentsize = half(46, "e_shentsize")? as usize;
        let shnum = half(48, "e_shnum")? as usize;
        let shstrndx = half(50, "e_shstrndx")? as usize;
        let mut segments = Vec::new();
        for i in 0..phnum {
            let at = phoff + i * phentsize;
            if field(at, "p_type")? != PT_LOAD {
                continue;
            }
            segments.push(Segment {
                run_addr: field(at + 8, "p_vaddr")?,
                load_addr: field(at + 12, "p_paddr")?,
                file_size: field(at + 16, "p_filesz")?,
                mem_size: field(at + 20, "p_memsz")?,
            });
        }
        let header = |i: usize| shoff + i * shentsize;
        let strtab_off = field(header(shstrndx) + 16, "shstrtab offset")? as usize;
        let mut sections = Vec::new();
        let mut symbols = Vec::new();
        for i in 0..shnum {
            let at = header(i);
            let name_off = field(at, "sh_name")? as usize;
            let kind = field(at + 4, "sh_type")?;
            let flags = field(at + 8, "sh_flags")?;
            let addr = field(at + 12, "sh_addr")?;
            let offset = field(at + 16, "sh_offset")? as usize;
            let size = field(at + 20, "sh_size")?;
            let link = field(at + 24, "sh_link")? as usize;
            let entsize = field(at + 36, "sh_entsize")? as usize;
            let name = cstr(b, strtab_off + name_off).ok_or(bad("section name"))?;
            if flags & SHF_ALLOC != 0 && size > 0 {
                sections.push(Section {
                    name,
                    addr,
                    size,
                    nobits: kind == SHT_NOBITS,
                });
            }
            if kind == SHT_SYMTAB && entsize >= 16 {
                let strings = field(header(link) + 16, "symbol strings")? as usize;
                for k in 0..(size as usize / entsize) {
                    let s = offset + k * entsize;
                    let n = field(s, "st_name")? as usize;
                    let value = field(s + 4, "st_value")?;
                    if n == 0 {
                        continue;
                    }
                    if let Some(sym) = cstr(b, strings + n) {
                        symbols.push((sym, value));
                    }
                }
            }
        }
        Ok(Firmware {
            path: path.to_path_buf(),
            bytes,
            sections,
            segments,
            symbols,
        })
    }

    /// A symbol's value (a function's address with the Thumb bit cleared).
    pub fn symbol(&self, name: &str) -> Result<u64, ImageError> {
        self.symbols
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| *v)
            .ok_or_else(|| ImageError::NoSymbol {
                path: self.path.clone(),
                name: name.to_string(),
            })
    }

    /// A function's first instruction.
    pub fn function(&self, name: &str) -> Result<u64, ImageError> {
        Ok(self.symbol(name)? & !1)
    }

    /// The image as rigless places it.
    pub fn rigless_image(&self) -> Result<rigless::image::Image, rigless::image::Error> {
        rigless::image::Image::new(&self.path, self.bytes.clone(), None)
    }

    /// How the image uses the STM32F405's memories.
    pub fn fit(&self) -> Fit {
        let flash_used: u64 = self
            .segments
            .iter()
            .filter(|s| s.file_size > 0)
            .map(|s| s.file_size)
            .sum();
        let ram = |r: &Region| -> u64 {
            self.sections
                .iter()
                .filter(|s| r.contains(s.addr, 0) && s.addr < r.base + r.size)
                .map(|s| s.size)
                .sum()
        };
        let mut outside = Vec::new();
        for s in &self.segments {
            if s.file_size > 0 && !FLASH.contains(s.load_addr, s.file_size) {
                outside.push(format!(
                    "stored bytes {:#010x}+{:#x} outside {}",
                    s.load_addr, s.file_size, FLASH.name
                ));
            }
        }
        for s in &self.sections {
            let inside = [FLASH, SRAM, CCM]
                .iter()
                .any(|r| r.contains(s.addr, s.size));
            if !inside {
                outside.push(format!(
                    "section {} at {:#010x}+{:#x} outside flash, SRAM and CCM",
                    s.name, s.addr, s.size
                ));
            }
        }
        let stack_top = self.symbol("_stack_start").ok();
        if let Some(top) = stack_top {
            let inside = [SRAM, CCM]
                .iter()
                .any(|r| top > r.base && top <= r.base + r.size);
            if !inside {
                outside.push(format!("_stack_start {top:#010x} outside SRAM and CCM"));
            }
        }
        Fit {
            flash_used,
            sram_used: ram(&SRAM),
            ccm_used: ram(&CCM),
            stack_top,
            outside,
        }
    }
}

/// How an image uses the part's memories.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fit {
    /// Flash bytes stored (code, read-only data, `.data`'s initial values).
    pub flash_used: u64,
    /// SRAM bytes of the sections placed there (`.data`, `.bss`, `.uninit`; the stack grows
    /// down from `_stack_start` into what is left).
    pub sram_used: u64,
    /// CCM bytes.
    pub ccm_used: u64,
    /// The initial stack pointer.
    pub stack_top: Option<u64>,
    /// Everything that lies outside the part's memories.
    pub outside: Vec<String>,
}

impl Fit {
    /// Everything inside flash 1 MiB, SRAM 128 KiB and CCM 64 KiB.
    pub fn fits(&self) -> bool {
        self.outside.is_empty()
            && self.flash_used <= FLASH.size
            && self.sram_used <= SRAM.size
            && self.ccm_used <= CCM.size
    }
}

impl std::fmt::Display for Fit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "flash {} B of {} ({:.1} %), SRAM {} B of {} ({:.1} %), CCM {} B of {}",
            self.flash_used,
            FLASH.size,
            100.0 * self.flash_used as f64 / FLASH.size as f64,
            self.sram_used,
            SRAM.size,
            100.0 * self.sram_used as f64 / SRAM.size as f64,
            self.ccm_used,
            CCM.size
        )?;
        for o in &self.outside {
            write!(f, "; {o}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic ELF with one section outside SRAM is refused, one inside fits.
    fn elf(sections: &[(&str, u32, u32, bool)]) -> Vec<u8> {
        // Header, then section headers, then the name table.
        let mut names = vec![0u8];
        let mut offs = Vec::new();
        for (n, ..) in sections {
            offs.push(names.len() as u32);
            names.extend_from_slice(n.as_bytes());
            names.push(0);
        }
        offs.push(names.len() as u32);
        names.extend_from_slice(b".shstrtab\0");
        let shnum = sections.len() + 2;
        let shoff = 52u32;
        let names_off = shoff + 40 * shnum as u32;
        let mut b = vec![0u8; 52];
        b[..4].copy_from_slice(b"\x7fELF");
        b[4] = 1;
        b[5] = 1;
        b[32..36].copy_from_slice(&shoff.to_le_bytes());
        b[46..48].copy_from_slice(&40u16.to_le_bytes());
        b[48..50].copy_from_slice(&(shnum as u16).to_le_bytes());
        b[50..52].copy_from_slice(&((shnum - 1) as u16).to_le_bytes());
        b.extend(vec![0u8; 40]);
        for (i, (_, addr, size, nobits)) in sections.iter().enumerate() {
            let mut h = vec![0u8; 40];
            h[0..4].copy_from_slice(&offs[i].to_le_bytes());
            h[4..8].copy_from_slice(&(if *nobits { 8u32 } else { 1 }).to_le_bytes());
            h[8..12].copy_from_slice(&2u32.to_le_bytes());
            h[12..16].copy_from_slice(&addr.to_le_bytes());
            h[20..24].copy_from_slice(&size.to_le_bytes());
            b.extend(h);
        }
        let mut h = vec![0u8; 40];
        h[0..4].copy_from_slice(&offs[sections.len()].to_le_bytes());
        h[4..8].copy_from_slice(&3u32.to_le_bytes());
        h[16..20].copy_from_slice(&names_off.to_le_bytes());
        h[20..24].copy_from_slice(&(names.len() as u32).to_le_bytes());
        b.extend(h);
        b.extend(names);
        b
    }

    #[test]
    fn sections_outside_the_f405_are_reported() {
        let ok = Firmware::parse(
            Path::new("ok"),
            elf(&[
                (".text", 0x0800_0000, 0x1000, false),
                (".bss", 0x2000_0000, 0x1_0000, true),
            ]),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        assert!(ok.fit().fits(), "{}", ok.fit());
        assert_eq!(ok.fit().sram_used, 0x1_0000);
        // 0x2002_0000 is past the F405's 128 KiB (the F427 would still have SRAM3 there).
        let big = Firmware::parse(
            Path::new("big"),
            elf(&[(".bss", 0x2001_f000, 0x2000, true)]),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        assert!(!big.fit().fits());
    }
}
