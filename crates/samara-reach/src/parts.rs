//! A run cut into parts computed apart and put back together exactly (`samara reach
//! --shard I/N`, `samara merge reach`).
//!
//! [`reach`](crate::reach) cuts the initial set into pieces (its initial partition along
//! the widest parameter), flies every sub-box over the horizon and splits the ones worth
//! it, round by round, within one budget of sub-boxes (`max_leaves`) counted over all
//! pieces. A sub-box's flight, and whether it is worth splitting, depend only on the
//! sub-box and on what every part computes alike: the settings and the simulated samples
//! (the falsification, the sampled range and the noise threshold drawn from it). Only the
//! budget ties the pieces together.
//!
//! So a part ([`Prepared::fly`]) flies a contiguous range of the pieces and refines them
//! with the driver's rule, counting every piece outside its range as one sub-box (the
//! fewest it can be), and records every sub-box it flew ([`Flown`], named by
//! [`piece_key`] and [`child_key`]). [`refine`] then replays the driver's rounds over all
//! pieces on the recorded flights, and [`finish`] orders the final sub-boxes and decides
//! as the driver does: the result is the one-process result, sub-box for sub-box.
//!
//! A part counts at most as many sub-boxes as the whole run at the same point of the
//! rounds (until it makes a split the run does not), so it splits every sub-box the run
//! splits; once the budget runs out during the refinement, a part may go on splitting
//! where the run stops (it cannot see the other parts' sub-boxes), and those extra
//! sub-boxes are recorded but not used. Every sub-box the replay needs was recorded,
//! except in one case: a half that only the part created loses its enclosure and is split
//! on the budget's extra quarter, leaving the part less of that quarter than the run
//! uses. [`refine`] then names the missing sub-box instead of guessing.
//!
//! There is one copy of the per-sub-box code: [`prepare`], [`Prepared`]'s flights,
//! [`refine`] and [`finish`] are the driver's own ([`reach`](crate::reach) is their
//! composition over all pieces). The figure of a merged run is drawn by
//! `samara_report::reach::draw`, in the one-process run's layout.

use std::ops::Range;

pub use crate::result::Flown;
pub use crate::zonotope::driver::{child_key, finish, piece_key, prepare, refine, Prepared};

/// A sub-box of the initial set and its enclosures, as a part records it: the driver's
/// [`Leaf`](crate::Leaf).
pub type LeafRecord = crate::result::Leaf;

impl Prepared<'_> {
    /// Fly the pieces `range` and refine them with the driver's rule (the pieces outside
    /// counted as one sub-box each); every sub-box flown, in flight order.
    pub fn fly(&self, range: Range<usize>) -> Vec<Flown> {
        let mut all: Vec<Flown> = Vec::new();
        self.refine_pieces(range, |round| all.extend(round.iter().cloned()));
        all
    }
}
