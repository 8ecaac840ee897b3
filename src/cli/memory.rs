//! How much memory a command may take before it starts: the least of what
//! the machine has free, what the process's control group (a container,
//! a Slurm job) may still use, and what its address-space limit
//! (`ulimit -v`) leaves. An allocation beyond it would abort the process
//! midway; a command compares its need with this up front instead.

/// Bytes this process may still allocate, as far as Linux tells; 4 GiB
/// where nothing can be read.
pub(crate) fn available_bytes() -> u64 {
    [
        machine_available(),
        control_group_available(),
        address_space_available(),
    ]
    .into_iter()
    .flatten()
    .min()
    .unwrap_or(4 << 30)
}

/// Memory a render of `width` × `height` pixels needs, in bytes: the film,
/// and as much again for the output encoder's buffers at the end.
pub(crate) fn render_needs(width: u32, height: u32) -> u64 {
    2 * u64::from(width) * u64::from(height) * lapidary::render::film::FILM_BYTES_PER_PIXEL
}

/// Gibibytes in `bytes`.
pub(crate) fn gib(bytes: u64) -> f64 {
    bytes as f64 / f64::from(1u32 << 30)
}

/// `bytes` for a message: in GiB from one GiB, else in MiB, else in KiB,
/// to three significant digits (a tiny film reads 8.38 KiB, not 0.0 MiB;
/// a message comparing with a limit adds the MiB).
pub(crate) fn amount(bytes: u64) -> String {
    let (value, unit) = if bytes >= 1 << 30 {
        (gib(bytes), "GiB")
    } else if bytes >= 1 << 20 {
        (bytes as f64 / f64::from(1u32 << 20), "MiB")
    } else {
        (bytes as f64 / 1024.0, "KiB")
    };
    let decimals = match value {
        v if v >= 100.0 => 0,
        v if v >= 10.0 => 1,
        _ => 2,
    };
    format!("{value:.decimals$} {unit}")
}

/// `MemAvailable` of /proc/meminfo.
fn machine_available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    kib_field(&text, "MemAvailable:")
}

/// The limit of the process's memory control group less its use: cgroup
/// v2 (`memory.max`, `memory.current`) or v1 (`memory.limit_in_bytes`,
/// `memory.usage_in_bytes`); `None` without a limit.
fn control_group_available() -> Option<u64> {
    let groups = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let read =
        |path: String| -> Option<u64> { std::fs::read_to_string(path).ok()?.trim().parse().ok() };
    for line in groups.lines() {
        let mut fields = line.splitn(3, ':');
        let (_, controllers, group) = (fields.next()?, fields.next()?, fields.next()?);
        let (limit, usage) = if controllers.is_empty() {
            let dir = format!("/sys/fs/cgroup{group}");
            (
                read(format!("{dir}/memory.max")),
                read(format!("{dir}/memory.current")),
            )
        } else if controllers.split(',').any(|c| c == "memory") {
            let dir = format!("/sys/fs/cgroup/memory{group}");
            (
                read(format!("{dir}/memory.limit_in_bytes")),
                read(format!("{dir}/memory.usage_in_bytes")),
            )
        } else {
            continue;
        };
        // v2 writes "max" (not a number) without a limit, v1 a number near 2⁶³.
        if let Some(limit) = limit.filter(|&limit| limit < 1 << 60) {
            return Some(limit.saturating_sub(usage.unwrap_or(0)));
        }
    }
    None
}

/// The soft address-space limit (`ulimit -v`) less the process's size now.
fn address_space_available() -> Option<u64> {
    let limits = std::fs::read_to_string("/proc/self/limits").ok()?;
    let limit: u64 = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?
        .split_whitespace()
        .nth(3)?
        .parse()
        .ok()?; // "unlimited" is no limit
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let size = kib_field(&status, "VmSize:").unwrap_or(0);
    Some(limit.saturating_sub(size))
}

/// The value in kB of the line starting with `key`, in bytes.
fn kib_field(text: &str, key: &str) -> Option<u64> {
    let kib: u64 = text
        .lines()
        .find(|l| l.starts_with(key))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()?;
    Some(kib * 1024)
}
