//! Disjoint sets over `0..n` (union by smallest index, path halving).
//!
//! Invariant: the representative of a set is its smallest member, so the
//! result of any sequence of unions does not depend on the order of the
//! `find` calls between them.

/// Disjoint sets over the indices `0..n`.
#[derive(Clone, Debug)]
pub struct UnionFind {
    parent: Vec<usize>,
}

impl UnionFind {
    /// `n` singletons.
    pub fn new(n: usize) -> UnionFind {
        UnionFind {
            parent: (0..n).collect(),
        }
    }

    /// The representative (smallest member) of `i`'s set.
    pub fn find(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    /// Joins the sets of `a` and `b`; returns the representative of the
    /// union.
    pub fn union(&mut self, a: usize, b: usize) -> usize {
        let (ra, rb) = (self.find(a), self.find(b));
        let (keep, drop) = (ra.min(rb), ra.max(rb));
        self.parent[drop] = keep;
        keep
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_smallest_member_represents_its_set() {
        let mut sets = UnionFind::new(6);
        sets.union(4, 2);
        sets.union(5, 4);
        sets.union(1, 3);
        assert_eq!(
            (0..6).map(|i| sets.find(i)).collect::<Vec<_>>(),
            [0, 1, 2, 1, 2, 2]
        );
        assert_eq!(sets.union(3, 5), 1);
        assert_eq!(sets.find(5), 1);
    }
}
