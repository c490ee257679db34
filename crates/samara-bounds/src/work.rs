//! The order of the searches' frontiers (input splitting in [`crate::search`] and
//! [`crate::smooth`], ReLU splitting in [`crate::relusplit`]):
//! a max-heap of pieces that pops the deepest piece first (depth first, so the frontier
//! stays small and pieces get cheap quickly), and among pieces of one depth the one
//! with the lowest key (the least constraint bound: closest to holding a point).

/// Implements `PartialEq`, `Eq`, `PartialOrd` and `Ord` for a piece type with fields
/// `depth: u32` and `key: f64`, in the order of the module documentation: greater is
/// deeper, then of lower key (`f64::total_cmp`). Two pieces are equal when neither goes
/// first.
macro_rules! deepest_then_least_key {
    ($t:ty) => {
        impl PartialEq for $t {
            fn eq(&self, o: &Self) -> bool {
                self.cmp(o).is_eq()
            }
        }
        impl Eq for $t {}
        impl PartialOrd for $t {
            fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
                Some(self.cmp(o))
            }
        }
        impl Ord for $t {
            fn cmp(&self, o: &Self) -> std::cmp::Ordering {
                self.depth.cmp(&o.depth).then(o.key.total_cmp(&self.key))
            }
        }
    };
}
pub(crate) use deepest_then_least_key;
