//! The per-node store: reference positions, volumes and every per-node array of a simulation
//! as named, typed columns, so that a change of the node set (particle splitting, activation
//! of a grid level, a reordering) resizes all of them in one place.
//!
//! Indices `0..owned()` are the nodes this process updates. A later distributed run would
//! append halo copies of other processes' nodes after them (`ghosts()`); today that range is
//! always empty.

use std::any::Any;
use std::marker::PhantomData;

/// A value stored once per node. Floating-point values (`f64`, `[f64; N]`) are exported as
/// point data with their component count; other per-node records are kept but not exported.
pub trait NodeValue: Copy + Send + Sync + 'static {
    /// The value of a node appended without a parent.
    const EMPTY: Self;

    /// The values as a flat float array and the count per node, if they are floats.
    fn floats(values: &[Self]) -> Option<(&[f64], usize)> {
        let _ = values;
        None
    }
}

impl NodeValue for f64 {
    const EMPTY: Self = 0.0;
    fn floats(values: &[f64]) -> Option<(&[f64], usize)> {
        Some((values, 1))
    }
}

impl<const N: usize> NodeValue for [f64; N] {
    const EMPTY: Self = [0.0; N];
    fn floats(values: &[[f64; N]]) -> Option<(&[f64], usize)> {
        Some((values.as_flattened(), N))
    }
}

impl NodeValue for u8 {
    const EMPTY: Self = 0;
}

impl NodeValue for u32 {
    const EMPTY: Self = 0;
}

/// A typed handle to one column of a [`Nodes`] store.
pub struct Field<T> {
    index: usize,
    _value: PhantomData<fn() -> T>,
}

impl<T> Clone for Field<T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T> Copy for Field<T> {}

impl<T> std::fmt::Debug for Field<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Field({})", self.index)
    }
}

trait Column: Send + Sync {
    fn name(&self) -> &'static str;
    /// Appends copies of the rows `parents`, or default values where a row is `u32::MAX`.
    fn append(&mut self, parents: &[u32]);
    /// Row k becomes the old row `order[k]`.
    fn permute(&mut self, order: &[u32]);
    fn floats(&self) -> Option<(&[f64], usize)>;
    fn bytes(&self) -> usize;
    fn as_any(&self) -> &dyn Any;
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

struct Typed<T> {
    name: &'static str,
    values: Vec<T>,
}

impl<T: NodeValue> Column for Typed<T> {
    fn name(&self) -> &'static str {
        self.name
    }

    fn append(&mut self, parents: &[u32]) {
        self.values.reserve(parents.len());
        for &p in parents {
            let v = if p == u32::MAX {
                T::EMPTY
            } else {
                self.values[p as usize]
            };
            self.values.push(v);
        }
    }

    fn permute(&mut self, order: &[u32]) {
        self.values = order.iter().map(|&k| self.values[k as usize]).collect();
    }

    fn floats(&self) -> Option<(&[f64], usize)> {
        T::floats(&self.values)
    }

    fn bytes(&self) -> usize {
        std::mem::size_of_val(self.values.as_slice())
    }

    fn as_any(&self) -> &dyn Any {
        &self.values
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        &mut self.values
    }
}

/// Reference positions and volumes of the nodes (read-only outside the store).
pub struct Base<const D: usize> {
    reference: Vec<[f64; D]>,
    volumes: Vec<f64>,
}

impl<const D: usize> Base<D> {
    pub fn reference(&self) -> &[[f64; D]] {
        &self.reference
    }

    pub fn volumes(&self) -> &[f64] {
        &self.volumes
    }
}

/// The named per-node columns (each as long as the node set; read and written as slices).
#[derive(Default)]
pub struct Columns {
    columns: Vec<Box<dyn Column>>,
    len: usize,
}

/// A handle used with a store it does not belong to, or with another type: a programming
/// error, not an input error.
const FOREIGN: &str = "a node field handle belongs to the store that created it";

impl Columns {
    /// A new column, every node starting at `initial`.
    pub fn add<T: NodeValue>(&mut self, name: &'static str, initial: T) -> Field<T> {
        self.add_values(name, vec![initial; self.len])
    }

    /// A new column with its values.
    pub fn add_values<T: NodeValue>(&mut self, name: &'static str, values: Vec<T>) -> Field<T> {
        assert_eq!(
            values.len(),
            self.len,
            "column `{name}`: one value per node"
        );
        self.columns.push(Box::new(Typed { name, values }));
        Field {
            index: self.columns.len() - 1,
            _value: PhantomData,
        }
    }

    pub fn get<T: NodeValue>(&self, field: Field<T>) -> &[T] {
        self.columns[field.index]
            .as_any()
            .downcast_ref::<Vec<T>>()
            .expect(FOREIGN)
    }

    pub fn get_mut<T: NodeValue>(&mut self, field: Field<T>) -> &mut [T] {
        self.columns[field.index]
            .as_any_mut()
            .downcast_mut::<Vec<T>>()
            .expect(FOREIGN)
    }

    /// Two different columns, both mutable.
    pub fn pair_mut<A: NodeValue, B: NodeValue>(
        &mut self,
        a: Field<A>,
        b: Field<B>,
    ) -> (&mut [A], &mut [B]) {
        let [ca, cb] = self
            .columns
            .get_disjoint_mut([a.index, b.index])
            .expect("two different node fields");
        (
            ca.as_any_mut().downcast_mut::<Vec<A>>().expect(FOREIGN),
            cb.as_any_mut().downcast_mut::<Vec<B>>().expect(FOREIGN),
        )
    }

    /// Three different columns, all mutable.
    pub fn triple_mut<A: NodeValue, B: NodeValue, C: NodeValue>(
        &mut self,
        a: Field<A>,
        b: Field<B>,
        c: Field<C>,
    ) -> (&mut [A], &mut [B], &mut [C]) {
        let [ca, cb, cc] = self
            .columns
            .get_disjoint_mut([a.index, b.index, c.index])
            .expect("three different node fields");
        (
            ca.as_any_mut().downcast_mut::<Vec<A>>().expect(FOREIGN),
            cb.as_any_mut().downcast_mut::<Vec<B>>().expect(FOREIGN),
            cc.as_any_mut().downcast_mut::<Vec<C>>().expect(FOREIGN),
        )
    }

    /// Four different columns, all mutable.
    pub fn quad_mut<A: NodeValue, B: NodeValue, C: NodeValue, E: NodeValue>(
        &mut self,
        a: Field<A>,
        b: Field<B>,
        c: Field<C>,
        e: Field<E>,
    ) -> (&mut [A], &mut [B], &mut [C], &mut [E]) {
        let [ca, cb, cc, ce] = self
            .columns
            .get_disjoint_mut([a.index, b.index, c.index, e.index])
            .expect("four different node fields");
        (
            ca.as_any_mut().downcast_mut::<Vec<A>>().expect(FOREIGN),
            cb.as_any_mut().downcast_mut::<Vec<B>>().expect(FOREIGN),
            cc.as_any_mut().downcast_mut::<Vec<C>>().expect(FOREIGN),
            ce.as_any_mut().downcast_mut::<Vec<E>>().expect(FOREIGN),
        )
    }

    /// Every float column: (name, values flat, components per node).
    pub fn float_fields(&self) -> impl Iterator<Item = (&'static str, &[f64], usize)> {
        self.columns
            .iter()
            .filter_map(|c| c.floats().map(|(v, n)| (c.name(), v, n)))
    }

    fn bytes(&self) -> usize {
        self.columns.iter().map(|c| c.bytes()).sum()
    }
}

/// Reference positions, volumes and named per-node columns, all of one length. The two
/// parts are separate fields so that a scheme can read the reference configuration while it
/// writes columns; only the store itself changes the node set.
pub struct Nodes<const D: usize> {
    pub base: Base<D>,
    pub fields: Columns,
    owned: usize,
}

impl<const D: usize> Nodes<D> {
    pub fn new(reference: Vec<[f64; D]>, volumes: Vec<f64>) -> Nodes<D> {
        assert_eq!(reference.len(), volumes.len(), "one volume per node");
        let owned = reference.len();
        Nodes {
            fields: Columns {
                columns: Vec::new(),
                len: owned,
            },
            base: Base { reference, volumes },
            owned,
        }
    }

    pub fn len(&self) -> usize {
        self.base.reference.len()
    }

    pub fn is_empty(&self) -> bool {
        self.base.reference.is_empty()
    }

    /// The nodes this process updates.
    pub fn owned(&self) -> std::ops::Range<usize> {
        0..self.owned
    }

    /// Halo copies of other processes' nodes (none yet: room for a distributed run).
    pub fn ghosts(&self) -> std::ops::Range<usize> {
        self.owned..self.len()
    }

    pub fn reference(&self) -> &[[f64; D]] {
        &self.base.reference
    }

    pub fn volumes(&self) -> &[f64] {
        &self.base.volumes
    }

    /// Appends nodes at `reference` with `volumes`; node k's columns start as copies of node
    /// `parents[k]`'s (children inherit their parent's state), or at `NodeValue::EMPTY` where
    /// `parents[k]` is `u32::MAX`. The caller then sets what must differ (e.g. a child's
    /// current position). Returns the new nodes' index range.
    pub fn append(
        &mut self,
        reference: &[[f64; D]],
        volumes: &[f64],
        parents: &[u32],
    ) -> std::ops::Range<usize> {
        assert!(
            reference.len() == volumes.len() && volumes.len() == parents.len(),
            "append: one position, volume and parent per new node"
        );
        assert!(self.ghosts().is_empty(), "append before any halo exists");
        let start = self.len();
        self.base.reference.extend_from_slice(reference);
        self.base.volumes.extend_from_slice(volumes);
        for c in &mut self.fields.columns {
            c.append(parents);
        }
        self.fields.len = self.len();
        self.owned = self.len();
        start..self.len()
    }

    /// Splits node `parent` into `reference.len()` children of `volume` each: the first takes
    /// the parent's index (its columns stay), the others are appended with copies of the
    /// parent's columns (particle splitting, zeng2024 (30)). Returns the appended range.
    pub fn split(
        &mut self,
        parent: usize,
        reference: &[[f64; D]],
        volume: f64,
    ) -> std::ops::Range<usize> {
        assert!(!reference.is_empty(), "split: at least one child");
        self.base.reference[parent] = reference[0];
        self.base.volumes[parent] = volume;
        let rest = reference.len() - 1;
        self.append(
            &reference[1..],
            &vec![volume; rest],
            &vec![parent as u32; rest],
        )
    }

    /// Reorders every array: node k becomes the old node `order[k]` (a permutation of
    /// 0..len). Indices held elsewhere (families, masks) must be remapped by the caller.
    pub fn permute(&mut self, order: &[u32]) {
        assert_eq!(
            order.len(),
            self.len(),
            "permute: a new place for every node"
        );
        let mut seen = vec![false; order.len()];
        for &k in order {
            assert!(
                !std::mem::replace(&mut seen[k as usize], true),
                "permute: node {k} appears twice"
            );
        }
        let base = &mut self.base;
        base.reference = order.iter().map(|&k| base.reference[k as usize]).collect();
        base.volumes = order.iter().map(|&k| base.volumes[k as usize]).collect();
        for c in &mut self.fields.columns {
            c.permute(order);
        }
    }

    /// Bytes held by the store.
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of_val(self.base.reference.as_slice())
            + std::mem::size_of_val(self.base.volumes.as_slice())
            + self.fields.bytes()
    }
}

impl<const D: usize> std::fmt::Debug for Nodes<D> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names: Vec<&str> = self.fields.columns.iter().map(|c| c.name()).collect();
        f.debug_struct("Nodes")
            .field("len", &self.len())
            .field("columns", &names)
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn append_and_permute_keep_every_column_aligned() {
        let mut nodes = Nodes::<2>::new(vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], vec![1.0; 3]);
        let velocity = nodes.fields.add("velocity", [0.0; 2]);
        let phase = nodes.fields.add("phase", 0u8);
        let concentration = nodes
            .fields
            .add_values("concentration", vec![10.0, 11.0, 12.0]);
        nodes.fields.get_mut(velocity)[1] = [5.0, 6.0];
        nodes.fields.get_mut(phase)[1] = 1;
        // Two children of node 1 and a node with default values.
        let new = nodes.append(
            &[[0.75, 0.0], [1.25, 0.0], [9.0, 9.0]],
            &[0.5, 0.5, 2.0],
            &[1, 1, u32::MAX],
        );
        assert_eq!(new, 3..6);
        assert_eq!(nodes.len(), 6);
        assert_eq!(nodes.fields.get(velocity)[4], [5.0, 6.0]);
        assert_eq!(nodes.fields.get(phase)[3], 1);
        assert_eq!(nodes.fields.get(concentration)[5], 0.0);
        assert_eq!(nodes.volumes()[5], 2.0);
        // Reverse the order: every column and the reference move together.
        let order: Vec<u32> = (0..6).rev().collect();
        nodes.permute(&order);
        assert_eq!(nodes.reference()[1], [1.25, 0.0]);
        assert_eq!(nodes.fields.get(velocity)[1], [5.0, 6.0]);
        assert_eq!(nodes.fields.get(concentration)[5], 10.0);
        assert_eq!(nodes.volumes()[0], 2.0);
        assert!(nodes.ghosts().is_empty());
        assert_eq!(nodes.owned(), 0..6);
        let floats: Vec<(&str, usize)> = nodes
            .fields
            .float_fields()
            .map(|(name, v, n)| {
                assert_eq!(v.len(), 6 * n);
                (name, n)
            })
            .collect();
        assert_eq!(floats, [("velocity", 2), ("concentration", 1)]);
        let (v, c) = nodes.fields.pair_mut(velocity, concentration);
        v[0][0] = c[0];
        assert_eq!(nodes.fields.get(velocity)[0][0], 0.0);
    }

    #[test]
    #[should_panic(expected = "appears twice")]
    fn a_permutation_must_not_repeat_a_node() {
        let mut nodes = Nodes::<1>::new(vec![[0.0], [1.0]], vec![1.0; 2]);
        nodes.permute(&[0, 0]);
    }
}
