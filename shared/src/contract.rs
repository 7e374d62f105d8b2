//! The node contract: the numbers that the firmware, the host (`accelcal flash`, `hil`, `monitor`),
//! xtask and the repository's `memory.x` must agree on, defined once.
//!
//! `memory.x` (repository root) is a linker script and cannot import these; this module's tests
//! parse it (embedded at compile time) and check its regions against the contract.

/// Start of the STM32L475VG's flash (RM0351 §3.3.1, Table 9).
pub const FLASH_BASE: u32 = 0x0800_0000;
/// Size of the whole flash: 1 MiB in two banks of 512 KiB.
pub const FLASH_SIZE: u32 = 1024 * 1024;
/// Size of one flash bank (RM0351 §3.3.1: bank 2 starts at 0x0808_0000 when BFB2 = 0).
pub const FLASH_BANK_SIZE: u32 = 512 * 1024;
/// Flash page (erase unit) size, 2 KiB (RM0351 §3.3.1).
pub const FLASH_PAGE_SIZE: u32 = 2048;
/// Start of SRAM1.
pub const RAM_BASE: u32 = 0x2000_0000;
/// Size of SRAM1 (SRAM2 at 0x1000_0000 is unused), 96 KiB.
pub const RAM_SIZE: u32 = 96 * 1024;

/// Number of record slots.
pub const N_SLOTS: usize = 2;
/// Size of one record slot: one flash page.
pub const SLOT_SIZE: usize = FLASH_PAGE_SIZE as usize;
/// Flash address of record slot 0: page 510, the second-to-last page of bank 2.
pub const SLOT0_ADDR: u32 = FLASH_BASE + FLASH_SIZE - (N_SLOTS * SLOT_SIZE) as u32;
/// Flash addresses of the two record slots (the last two pages of flash).
pub const SLOT_ADDRS: [u32; N_SLOTS] = [SLOT0_ADDR, SLOT0_ADDR + SLOT_SIZE as u32];
/// End of the application's flash region (`FLASH` in `memory.x`): the record slots follow it.
pub const APP_FLASH_END: u32 = SLOT0_ADDR;

/// Address of the MCU's 96-bit unique device id (RM0351 §50.1, "Unique device ID register").
pub const UID_ADDR: u32 = 0x1FFF_7590;
/// Device id the QEMU board reports: QEMU 10 does not map the unique-id area, so records meant
/// for the emulated node carry this id.
pub const QEMU_DEVICE_ID: [u8; 12] = *b"QEMU-B-L475E";

/// Start of SRAM2 (32 KiB): the application does not use it (`memory.x` has no region there).
pub const SRAM2_BASE: u32 = 0x1000_0000;
/// Where the emulator puts an emulated node's device id: the first 16 bytes of SRAM2, which QEMU
/// maps and the application never touches. QEMU's generic loader writes them before boot (and
/// again at each system reset); the QEMU board reads them there ([`qemu_device_id`]). The real
/// board reads its unique-id register and never this area.
pub const QEMU_ID_ADDR: u32 = SRAM2_BASE;
/// Marks the block at [`QEMU_ID_ADDR`] as holding a device id (SRAM2 reads zeros otherwise).
pub const QEMU_ID_MAGIC: [u8; 4] = *b"NdID";
/// Size of the block at [`QEMU_ID_ADDR`]: the magic, then the 12-byte id.
pub const QEMU_ID_BLOCK_LEN: usize = 16;

/// The block the emulator loads at [`QEMU_ID_ADDR`] for a node reporting `id`.
pub const fn qemu_id_block(id: [u8; 12]) -> [u8; QEMU_ID_BLOCK_LEN] {
    let mut b = [0u8; QEMU_ID_BLOCK_LEN];
    let mut i = 0;
    while i < 4 {
        b[i] = QEMU_ID_MAGIC[i];
        i += 1;
    }
    while i < QEMU_ID_BLOCK_LEN {
        b[i] = id[i - 4];
        i += 1;
    }
    b
}

/// The device id a QEMU node reports given the block at [`QEMU_ID_ADDR`]: its id when the block
/// starts with [`QEMU_ID_MAGIC`], else [`QEMU_DEVICE_ID`] (nothing was loaded).
pub fn qemu_device_id(block: [u8; QEMU_ID_BLOCK_LEN]) -> [u8; 12] {
    let (magic, id) = block.split_at(4);
    match id.try_into() {
        Ok(id) if magic == QEMU_ID_MAGIC => id,
        _ => QEMU_DEVICE_ID,
    }
}

/// The device id of emulated node `index` (0-based) of `accelcal emulate`: node 0 is
/// [`QEMU_DEVICE_ID`] (no block loaded), node `i` ≥ 1 `QEMU-NODE-NN` with NN = i + 1 in two
/// decimal digits (`None` from index 99 on).
pub const fn qemu_node_id(index: usize) -> Option<[u8; 12]> {
    if index == 0 {
        return Some(QEMU_DEVICE_ID);
    }
    let n = index + 1;
    if n > 99 {
        return None;
    }
    let mut id = *b"QEMU-NODE-00";
    id[10] = b'0' + (n / 10) as u8;
    id[11] = b'0' + (n % 10) as u8;
    Some(id)
}

/// USART1 baud rate of the real board (ST-LINK virtual COM port).
pub const BAUD_REAL: u32 = 921_600;
/// USART1 baud rate of the QEMU board (QEMU ignores it; the emulated BRR is set from it).
pub const BAUD_QEMU: u32 = 115_200;

/// Scale of the fixed-point output (`Block::CalibratedFixed`): m/s² · 2¹⁶.
pub const FIXED_SCALE: f64 = 65536.0;
/// Fraction bits of the fixed-point output.
pub const FIXED_FRAC_BITS: u32 = 16;

const _: () = assert!(FIXED_SCALE == (1u64 << FIXED_FRAC_BITS) as f64);
const _: () = assert!(SLOT_ADDRS[1] + SLOT_SIZE as u32 == FLASH_BASE + FLASH_SIZE);
const _: () = assert!(SLOT0_ADDR.is_multiple_of(FLASH_PAGE_SIZE));
// Both slots lie in bank 2, which the ECC decision ([`crate::flash_ecc`]) relies on.
const _: () = assert!(SLOT0_ADDR >= FLASH_BASE + FLASH_BANK_SIZE);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_contract_literals() {
        assert_eq!(SLOT_ADDRS, [0x080F_F000, 0x080F_F800]);
        assert_eq!(APP_FLASH_END - FLASH_BASE, 1020 * 1024);
        assert_eq!(RAM_BASE + RAM_SIZE, 0x2001_8000);
        assert_eq!(FIXED_SCALE, 65536.0);
        assert_eq!(&QEMU_DEVICE_ID, b"QEMU-B-L475E");
        assert_eq!(QEMU_ID_ADDR, 0x1000_0000);
        assert_eq!(&qemu_id_block(*b"QEMU-NODE-02"), b"NdIDQEMU-NODE-02");
    }

    #[test]
    fn the_qemu_node_ids() {
        assert_eq!(qemu_node_id(0), Some(QEMU_DEVICE_ID));
        assert_eq!(qemu_node_id(1), Some(*b"QEMU-NODE-02"));
        assert_eq!(qemu_node_id(98), Some(*b"QEMU-NODE-99"));
        assert_eq!(qemu_node_id(99), None);
        // A loaded block gives its id back; SRAM2 as QEMU starts it (zeros), or anything without
        // the magic, gives the fixed id.
        let id = qemu_node_id(5).unwrap();
        assert_eq!(qemu_device_id(qemu_id_block(id)), id);
        assert_eq!(qemu_device_id([0; QEMU_ID_BLOCK_LEN]), QEMU_DEVICE_ID);
        assert_eq!(qemu_device_id([0xff; QEMU_ID_BLOCK_LEN]), QEMU_DEVICE_ID);
        let mut bad = qemu_id_block(id);
        bad[0] ^= 1;
        assert_eq!(qemu_device_id(bad), QEMU_DEVICE_ID);
    }

    /// The repository's linker script.
    const MEMORY_X: &str = include_str!("../../memory.x");

    /// A number of a linker script: decimal or `0x` hex, with an optional `K` or `M` suffix.
    fn number(s: &str) -> u32 {
        let s = s.trim();
        let (digits, scale) = match s.strip_suffix('K').or_else(|| s.strip_suffix('k')) {
            Some(d) => (d, 1024),
            None => match s.strip_suffix('M') {
                Some(d) => (d, 1024 * 1024),
                None => (s, 1),
            },
        };
        let v = match digits.strip_prefix("0x").or_else(|| digits.strip_prefix("0X")) {
            Some(h) => u32::from_str_radix(h, 16),
            None => digits.parse(),
        };
        v.unwrap_or_else(|e| panic!("memory.x: bad number `{s}`: {e}")) * scale
    }

    /// The regions of the script's MEMORY block: (name, origin, length).
    fn regions(script: &str) -> std::vec::Vec<(std::string::String, u32, u32)> {
        let start = script.find("MEMORY").expect("memory.x has a MEMORY block");
        let body = &script[start..];
        let body = &body[body.find('{').unwrap() + 1..body.find('}').unwrap()];
        body.lines()
            .filter(|l| l.contains("ORIGIN"))
            .map(|l| {
                let (name, rest) = l.split_once(':').expect("NAME : ORIGIN = …, LENGTH = …");
                let origin = rest.split("ORIGIN").nth(1).unwrap().split(',').next().unwrap();
                let length = rest.split("LENGTH").nth(1).unwrap();
                let value = |f: &str| number(f.trim_start().trim_start_matches('=').trim());
                (name.trim().into(), value(origin), value(length))
            })
            .collect()
    }

    #[test]
    fn memory_x_agrees_with_the_contract() {
        let r = regions(MEMORY_X);
        let get = |n: &str| {
            let (_, o, l) = r.iter().find(|(name, _, _)| name == n).unwrap_or_else(|| panic!("no {n}"));
            (*o, *l)
        };
        assert_eq!(get("FLASH"), (FLASH_BASE, APP_FLASH_END - FLASH_BASE));
        assert_eq!(get("RECORDS"), (SLOT_ADDRS[0], (N_SLOTS * SLOT_SIZE) as u32));
        assert_eq!(get("RAM"), (RAM_BASE, RAM_SIZE));
        assert_eq!(r.len(), 3, "{r:?}");
        // The emulated node's id block lies outside every region the linker places things in.
        let id = QEMU_ID_ADDR..QEMU_ID_ADDR + QEMU_ID_BLOCK_LEN as u32;
        for (name, o, l) in &r {
            assert!(id.end <= *o || id.start >= o + l, "the QEMU id block overlaps {name}");
        }
    }

    #[test]
    fn the_memory_x_parser_reads_what_it_is_given() {
        let r = regions(
            "MEMORY\n{\n  A : ORIGIN = 0x08000000, LENGTH = 1020K\n  B : ORIGIN = 4096, LENGTH = 1M\n}\n",
        );
        assert_eq!(r, [("A".into(), 0x0800_0000, 1020 * 1024), ("B".into(), 4096, 1024 * 1024)]);
    }
}
