//! Dependence sets: which variables an expression node depends on, kept in every node so that
//! ∂/∂x skips a subexpression without x at once (issue 27: the derivative of a flat sum of 2n
//! terms along x_i visits only the terms that hold x_i, not the whole sum).
//!
//! A set is sorted and without repeats. Constants have none and most nodes of a model one or
//! two, so those are stored inline; larger sets are shared slices, and a node whose set equals
//! one of its operands' (the common case: `a·b` with b constant, `sin(a)`, a sum of terms in
//! the same coordinates) shares that operand's slice rather than copying it.

use std::sync::Arc;

/// The variables a node depends on (sorted, distinct).
#[derive(Clone, PartialEq, Eq, Default)]
pub(super) enum Deps {
    /// A constant.
    #[default]
    None,
    /// One variable.
    One(u32),
    /// Two variables, the first smaller.
    Two([u32; 2]),
    /// Three or more, sorted.
    Many(Arc<[u32]>),
}

impl std::fmt::Debug for Deps {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.as_slice().iter()).finish()
    }
}

impl Deps {
    /// The set as a sorted slice.
    pub(super) fn as_slice(&self) -> &[u32] {
        match self {
            Deps::None => &[],
            Deps::One(a) => std::slice::from_ref(a),
            Deps::Two(ab) => ab,
            Deps::Many(s) => s,
        }
    }

    /// Iterates the variables in increasing order.
    pub(super) fn iter(&self) -> impl Iterator<Item = u32> + '_ {
        self.as_slice().iter().copied()
    }

    /// Number of variables.
    pub(super) fn len(&self) -> usize {
        self.as_slice().len()
    }

    /// Whether `x` is in the set.
    #[inline]
    pub(super) fn contains(&self, x: u32) -> bool {
        match self {
            Deps::None => false,
            Deps::One(a) => *a == x,
            Deps::Two([a, b]) => *a == x || *b == x,
            Deps::Many(s) => s.binary_search(&x).is_ok(),
        }
    }

    /// The set of one variable.
    pub(super) fn var(i: usize) -> Deps {
        Deps::One(u32::try_from(i).unwrap_or(u32::MAX))
    }

    /// From a sorted, distinct list.
    fn from_sorted(v: &[u32]) -> Deps {
        match *v {
            [] => Deps::None,
            [a] => Deps::One(a),
            [a, b] => Deps::Two([a, b]),
            _ => Deps::Many(v.into()),
        }
    }

    /// a ∪ b; shares a or b when the union is one of them.
    pub(super) fn union(a: &Deps, b: &Deps) -> Deps {
        if b.len() == 0 || a == b {
            return a.clone();
        }
        if a.len() == 0 {
            return b.clone();
        }
        // Whether the smaller set is inside the larger one: then the union is the larger.
        let (big, small) = if a.len() >= b.len() { (a, b) } else { (b, a) };
        if small.iter().all(|x| big.contains(x)) {
            return big.clone();
        }
        let mut out = Vec::with_capacity(a.len() + b.len());
        let (mut ia, mut ib) = (a.iter().peekable(), b.iter().peekable());
        loop {
            match (ia.peek().copied(), ib.peek().copied()) {
                (Some(x), Some(y)) => {
                    if x <= y {
                        out.push(x);
                        ia.next();
                        if x == y {
                            ib.next();
                        }
                    } else {
                        out.push(y);
                        ib.next();
                    }
                }
                (Some(x), None) => {
                    out.push(x);
                    ia.next();
                }
                (None, Some(y)) => {
                    out.push(y);
                    ib.next();
                }
                (None, None) => break,
            }
        }
        Deps::from_sorted(&out)
    }
}

#[cfg(test)]
mod tests {
    use super::Deps;

    fn set(v: &[u32]) -> Deps {
        Deps::from_sorted(v)
    }

    #[test]
    fn union_merges_shares_and_stays_sorted() {
        let a = set(&[1, 4, 9]);
        let b = set(&[2, 4]);
        let u = Deps::union(&a, &b);
        assert_eq!(u.iter().collect::<Vec<_>>(), [1, 2, 4, 9]);
        // A subset: the larger set itself, shared.
        let s = Deps::union(&a, &set(&[4, 9]));
        assert!(matches!((&s, &a), (Deps::Many(x), Deps::Many(y)) if std::sync::Arc::ptr_eq(x, y)));
        assert_eq!(Deps::union(&Deps::None, &b), b);
        assert_eq!(
            Deps::union(&Deps::var(3), &Deps::var(1))
                .iter()
                .collect::<Vec<_>>(),
            [1, 3]
        );
        assert!(u.contains(2) && !u.contains(3) && set(&[5, 7]).contains(7));
        assert_eq!(u.len(), 4);
    }
}
