//! The memory budget of a network's import: what the loaded network and its dense
//! lowering may take, instead of fixed caps on widths and tensor sizes.
//!
//! Import converts every constant tensor to f64 and builds dense affine maps (the chain
//! IR's [`crate::Affine`]); a file only declares shapes, so a corrupt or malicious file
//! could otherwise make samara allocate without bound. Every allocation the importers
//! make in proportion to a declared shape is first charged to a [`Budget`] (8 bytes per
//! f64 value, cumulative over the import): once the sum would pass the allowed bytes,
//! import stops with an error naming the tensor or node, the bytes needed and allowed,
//! and the environment variable [`IMPORT_MEMORY_ENV`] that raises the limit. Wide
//! networks with few inputs (VNN-COMP's tllverifybench: 2 inputs, 4096 x 8192 weights,
//! about 1 GB in all) load; a file declaring a terabyte does not, before anything of
//! that size is allocated.

use std::cell::Cell;
use std::time::Instant;

/// The environment variable that sets the import budget: bytes, or a number with a
/// `K`, `M`, `G` or `T` suffix (powers of 1024), e.g. `SAMARA_IMPORT_MEMORY=16G`.
pub const IMPORT_MEMORY_ENV: &str = "SAMARA_IMPORT_MEMORY";

/// The default budget, 8 GiB: a third of the 24 GiB machine samara is sized for,
/// leaving the rest to the verifier's own copies of the weights and its bounds.
pub const DEFAULT_IMPORT_MEMORY: u64 = 8 << 30;

/// Parse a size: bytes, or a number with a `K`, `M`, `G` or `T` suffix (an optional
/// trailing `B` or `iB` is accepted: `512M`, `8GiB`, `1.5G`).
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let t = t
        .strip_suffix("iB")
        .or_else(|| t.strip_suffix("ib"))
        .or_else(|| t.strip_suffix(['B', 'b']))
        .unwrap_or(t);
    let (num, mult) = match t.chars().last() {
        Some('k' | 'K') => (&t[..t.len() - 1], 1u64 << 10),
        Some('m' | 'M') => (&t[..t.len() - 1], 1 << 20),
        Some('g' | 'G') => (&t[..t.len() - 1], 1 << 30),
        Some('t' | 'T') => (&t[..t.len() - 1], 1 << 40),
        _ => (t, 1),
    };
    let bad =
        || format!("`{s}` is not a size; give bytes or a number with K, M, G or T (e.g. 16G)");
    let v: f64 = num.trim().parse().map_err(|_| bad())?;
    if !v.is_finite() || v <= 0.0 {
        return Err(bad());
    }
    let bytes = v * mult as f64;
    Ok(if bytes >= u64::MAX as f64 {
        u64::MAX
    } else {
        bytes as u64
    })
}

/// The import budget in bytes: [`IMPORT_MEMORY_ENV`] if set, else
/// [`DEFAULT_IMPORT_MEMORY`]; `Err` (a message naming the variable) on a value that is
/// not a size.
pub fn import_memory() -> Result<u64, String> {
    match std::env::var(IMPORT_MEMORY_ENV) {
        Ok(v) => parse_size(&v).map_err(|e| format!("{IMPORT_MEMORY_ENV}={e}")),
        Err(_) => Ok(DEFAULT_IMPORT_MEMORY),
    }
}

/// Most f64 values one tensor may hold while evaluating a graph: the whole import
/// budget (an invalid [`IMPORT_MEMORY_ENV`] counts as the default here; import itself
/// reports it).
pub fn max_tensor_values() -> usize {
    let bytes = import_memory().unwrap_or(DEFAULT_IMPORT_MEMORY);
    usize::try_from(bytes / 8).unwrap_or(usize::MAX)
}

/// A byte size for messages: `1,234,567,890 bytes (1.15 GiB)`.
pub fn show_bytes(b: u64) -> String {
    let digits = b.to_string();
    let mut grouped = String::new();
    for (k, c) in digits.chars().enumerate() {
        if k > 0 && (digits.len() - k).is_multiple_of(3) {
            grouped.push(',');
        }
        grouped.push(c);
    }
    format!(
        "{grouped} bytes ({:.2} GiB)",
        b as f64 / (1u64 << 30) as f64
    )
}

/// The memory one import may take, charged before each allocation that grows with a
/// declared shape (see the module documentation).
///
/// It also carries the import's deadline, if any: the caller's time limit (`samara
/// vnncomp`, `verify-vnnlib --timeout`) counts the import, and lowering an image-sized
/// network takes minutes, so the long loops of import and lowering ask
/// [`Budget::check_time`] and stop with [`TIMED_OUT`] once it has passed.
#[derive(Debug)]
pub struct Budget {
    allowed: u64,
    used: Cell<u64>,
    deadline: Option<Instant>,
}

/// The message of an import stopped by its deadline ([`Budget::check_time`]); the
/// importers turn it into [`crate::onnx::OnnxError::Timeout`].
pub const TIMED_OUT: &str = "the time limit ran out while loading the network";

impl Budget {
    /// A budget of `allowed` bytes.
    pub fn new(allowed: u64) -> Self {
        Budget {
            allowed,
            used: Cell::new(0),
            deadline: None,
        }
    }

    /// The same budget with a deadline (`None`: no time limit).
    pub fn with_deadline(mut self, deadline: Option<Instant>) -> Self {
        self.deadline = deadline;
        self
    }

    /// The deadline, if any.
    pub fn deadline(&self) -> Option<Instant> {
        self.deadline
    }

    /// `Err(`[`TIMED_OUT`]`)` once the deadline has passed. Cheap (one clock read):
    /// called once per node and every few thousand columns or rows of a long loop.
    pub fn check_time(&self) -> Result<(), String> {
        match self.deadline {
            Some(d) if Instant::now() >= d => Err(TIMED_OUT.to_string()),
            _ => Ok(()),
        }
    }

    /// The budget of [`import_memory`].
    pub fn from_env() -> Result<Self, String> {
        import_memory().map(Budget::new)
    }

    /// Bytes allowed.
    pub fn allowed(&self) -> u64 {
        self.allowed
    }

    /// Bytes charged so far.
    pub fn used(&self) -> u64 {
        self.used.get()
    }

    /// Charge `values` f64 values (8 bytes each) for `what` (e.g. "tensor `W`"); `Err`
    /// with the message to show if the import would then need more than allowed (and
    /// nothing is charged).
    pub fn charge(&self, values: usize, what: &dyn Fn() -> String) -> Result<(), String> {
        let need = (values as u64).saturating_mul(8);
        let total = self.used.get().saturating_add(need);
        if total > self.allowed {
            return Err(format!(
                "{} needs {}, and the import {} in all, more than the {} samara allows for \
                 a network's import; if the machine has the memory, raise the limit with \
                 the environment variable {IMPORT_MEMORY_ENV} (e.g. {IMPORT_MEMORY_ENV}=16G)",
                what(),
                show_bytes(need),
                show_bytes(total),
                show_bytes(self.allowed)
            ));
        }
        self.used.set(total);
        Ok(())
    }

    /// Whether `values` f64 values would fit in what is left (nothing is charged).
    pub fn fits(&self, values: usize) -> bool {
        (values as u64)
            .saturating_mul(8)
            .saturating_add(self.used.get())
            <= self.allowed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_suffixes_and_bad_ones_are_named() {
        assert_eq!(parse_size("4096").unwrap(), 4096);
        assert_eq!(parse_size("8G").unwrap(), 8 << 30);
        assert_eq!(parse_size("8GiB").unwrap(), 8 << 30);
        assert_eq!(parse_size("512m").unwrap(), 512 << 20);
        assert_eq!(parse_size("1.5K").unwrap(), 1536);
        assert_eq!(parse_size(" 2T ").unwrap(), 2 << 40);
        for bad in ["", "x", "-1G", "0", "G", "nanM", "1e400"] {
            let e = parse_size(bad).unwrap_err();
            assert!(e.contains("is not a size"), "{bad}: {e}");
        }
    }

    #[test]
    fn a_budget_charges_cumulatively_and_refuses_past_its_bytes() {
        let b = Budget::new(100);
        b.charge(10, &|| "a".into()).unwrap();
        assert_eq!(b.used(), 80);
        assert!(b.fits(2) && !b.fits(3));
        let e = b.charge(3, &|| "tensor `W`".into()).unwrap_err();
        assert!(e.contains("tensor `W` needs 24 bytes"), "{e}");
        assert!(e.contains("104 bytes"), "{e}");
        assert!(e.contains("the 100 bytes"), "{e}");
        assert!(e.contains(IMPORT_MEMORY_ENV), "{e}");
        // A refused charge leaves the budget as it was.
        assert_eq!(b.used(), 80);
        b.charge(2, &|| "b".into()).unwrap();
        assert_eq!(b.used(), 96);
        // An overflowing request is refused, not wrapped.
        assert!(b.charge(usize::MAX, &|| "c".into()).is_err());
    }

    #[test]
    fn byte_counts_read_with_thousands_separators() {
        assert_eq!(show_bytes(0), "0 bytes (0.00 GiB)");
        assert_eq!(show_bytes(1234567), "1,234,567 bytes (0.00 GiB)");
        assert_eq!(show_bytes(8 << 30), "8,589,934,592 bytes (8.00 GiB)");
    }
}
