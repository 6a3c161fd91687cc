//! A compact bounding volume hierarchy: binned SAH build (Wald 2007), flattened nodes with
//! adjacent children, front-to-back stack traversal. Primitives are opaque to it: the caller
//! passes their boxes at build time and an intersection closure at query time.

use crate::geom::{axis, Aabb, Ray, V3};

const BINS: usize = 16;
const MAX_LEAF: usize = 4;
/// Cost of one node traversal relative to one primitive test.
const TRAVERSAL_COST: f32 = 1.0;

#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    /// Leaf: first index into `order`; interior: index of the left child (right = left + 1).
    first: u32,
    /// Number of primitives (0 for an interior node).
    count: u32,
    /// Split axis of an interior node (picks the near child first).
    axis: u8,
}

/// A BVH over `n` primitives.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    order: Vec<u32>,
}

struct BuildPrim {
    bounds: Aabb,
    centroid: V3,
}

impl Bvh {
    /// Builds the hierarchy from the primitives' boxes.
    #[must_use]
    pub fn build(boxes: &[Aabb]) -> Self {
        if boxes.is_empty() {
            return Self::default();
        }
        let prims: Vec<BuildPrim> = boxes.iter().map(|b| BuildPrim { bounds: *b, centroid: b.center() }).collect();
        let mut order: Vec<u32> = (0..boxes.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * boxes.len());
        nodes.push(Node { bounds: Aabb::empty(), first: 0, count: boxes.len() as u32, axis: 0 });
        let mut stack = vec![0usize];
        while let Some(ni) = stack.pop() {
            let (first, count) = (nodes[ni].first as usize, nodes[ni].count as usize);
            let slice = &mut order[first..first + count];
            let mut bounds = Aabb::empty();
            let mut cbounds = Aabb::empty();
            for &p in slice.iter() {
                bounds = bounds.union(prims[p as usize].bounds);
                cbounds.grow(prims[p as usize].centroid);
            }
            nodes[ni].bounds = bounds;
            if count <= MAX_LEAF {
                continue;
            }
            let Some((ax, split)) = best_split(&prims, slice, &bounds, &cbounds) else { continue };
            // Partition by bin index.
            let lo = axis(cbounds.min, ax);
            let ext = axis(cbounds.max, ax) - lo;
            let k = BINS as f32 / ext;
            let bin_of = |p: u32| (((axis(prims[p as usize].centroid, ax) - lo) * k) as usize).min(BINS - 1);
            let mut i = 0;
            let mut j = slice.len();
            while i < j {
                if bin_of(slice[i]) < split {
                    i += 1;
                } else {
                    j -= 1;
                    slice.swap(i, j);
                }
            }
            if i == 0 || i == slice.len() {
                continue;
            }
            let left = nodes.len();
            nodes.push(Node { bounds: Aabb::empty(), first: first as u32, count: i as u32, axis: 0 });
            nodes.push(Node { bounds: Aabb::empty(), first: (first + i) as u32, count: (count - i) as u32, axis: 0 });
            nodes[ni] = Node { bounds, first: left as u32, count: 0, axis: ax as u8 };
            stack.push(left);
            stack.push(left + 1);
        }
        Self { nodes, order }
    }

    /// Bounds of everything (empty box for an empty hierarchy).
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        self.nodes.first().map_or(Aabb::empty(), |n| n.bounds)
    }

    /// Number of nodes (diagnostics).
    #[must_use]
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Visits the primitives the ray may hit, nearest boxes first. `test(prim, tmax)` returns
    /// the hit distance if the primitive is hit closer than `tmax`; `ray.tmax` shrinks to the
    /// closest hit. With `any_hit` the search stops at the first hit. Returns whether
    /// anything was hit.
    #[inline]
    pub fn traverse(&self, ray: &mut Ray, any_hit: bool, mut test: impl FnMut(u32, f32) -> Option<f32>) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let inv = crate::geom::v3(1.0 / ray.d.x, 1.0 / ray.d.y, 1.0 / ray.d.z);
        let neg = [ray.d.x < 0.0, ray.d.y < 0.0, ray.d.z < 0.0];
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        let mut hit = false;
        let mut ni = 0usize;
        if self.nodes[0].bounds.hit(ray.o, inv, ray.tmax).is_none() {
            return false;
        }
        loop {
            let node = &self.nodes[ni];
            if node.count > 0 {
                let first = node.first as usize;
                for &p in &self.order[first..first + node.count as usize] {
                    if let Some(t) = test(p, ray.tmax) {
                        if t < ray.tmax {
                            ray.tmax = t;
                            hit = true;
                            if any_hit {
                                return true;
                            }
                        }
                    }
                }
            } else {
                let (mut a, mut b) = (node.first as usize, node.first as usize + 1);
                if neg[node.axis as usize] {
                    std::mem::swap(&mut a, &mut b);
                }
                let ta = self.nodes[a].bounds.hit(ray.o, inv, ray.tmax);
                let tb = self.nodes[b].bounds.hit(ray.o, inv, ray.tmax);
                match (ta, tb) {
                    (Some(x), Some(y)) => {
                        let (near, far) = if x <= y { (a, b) } else { (b, a) };
                        if sp < stack.len() {
                            stack[sp] = far as u32;
                            sp += 1;
                        }
                        ni = near;
                        continue;
                    }
                    (Some(_), None) => {
                        ni = a;
                        continue;
                    }
                    (None, Some(_)) => {
                        ni = b;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next node whose box is still in reach.
            loop {
                if sp == 0 {
                    return hit;
                }
                sp -= 1;
                let cand = stack[sp] as usize;
                if self.nodes[cand].bounds.hit(ray.o, inv, ray.tmax).is_some() {
                    ni = cand;
                    break;
                }
            }
        }
    }
}

/// Best SAH split over all axes: (axis, first bin of the right side), or `None` if a leaf is
/// cheaper.
fn best_split(prims: &[BuildPrim], slice: &[u32], bounds: &Aabb, cbounds: &Aabb) -> Option<(usize, usize)> {
    let leaf_cost = slice.len() as f32;
    let parent_area = bounds.half_area().max(1e-30);
    let mut best: Option<(usize, usize, f32)> = None;
    for ax in 0..3 {
        let lo = axis(cbounds.min, ax);
        let ext = axis(cbounds.max, ax) - lo;
        if !(ext > 1e-12) {
            continue;
        }
        let k = BINS as f32 / ext;
        let mut bin_box = [Aabb::empty(); BINS];
        let mut bin_count = [0u32; BINS];
        for &p in slice {
            let b = (((axis(prims[p as usize].centroid, ax) - lo) * k) as usize).min(BINS - 1);
            bin_box[b] = bin_box[b].union(prims[p as usize].bounds);
            bin_count[b] += 1;
        }
        // Sweep from the right to get suffix areas and counts.
        let mut right_area = [0.0f32; BINS];
        let mut right_count = [0u32; BINS];
        let (mut acc, mut cnt) = (Aabb::empty(), 0u32);
        for b in (1..BINS).rev() {
            acc = acc.union(bin_box[b]);
            cnt += bin_count[b];
            right_area[b] = acc.half_area();
            right_count[b] = cnt;
        }
        let (mut acc, mut cnt) = (Aabb::empty(), 0u32);
        for split in 1..BINS {
            acc = acc.union(bin_box[split - 1]);
            cnt += bin_count[split - 1];
            if cnt == 0 || right_count[split] == 0 {
                continue;
            }
            let cost = TRAVERSAL_COST
                + (acc.half_area() * cnt as f32 + right_area[split] * right_count[split] as f32) / parent_area;
            if best.is_none_or(|(_, _, c)| cost < c) {
                best = Some((ax, split, cost));
            }
        }
    }
    let (ax, split, cost) = best?;
    (cost < leaf_cost || slice.len() > 4 * MAX_LEAF).then_some((ax, split))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::v3;

    /// Unit boxes on a grid: the BVH must find exactly what a brute-force loop finds.
    #[test]
    fn matches_brute_force() {
        let mut boxes = Vec::new();
        for i in 0..10 {
            for j in 0..10 {
                for k in 0..5 {
                    let c = v3(i as f32 * 2.0, j as f32 * 2.0, k as f32 * 3.0);
                    boxes.push(Aabb { min: c - v3(0.4, 0.4, 0.4), max: c + v3(0.4, 0.4, 0.4) });
                }
            }
        }
        let bvh = Bvh::build(&boxes);
        let mut rng = lacquer::rng::Pcg32::new(7, 0);
        for _ in 0..2000 {
            let o = v3(rng.range(-5.0, 25.0) as f32, rng.range(-5.0, 25.0) as f32, rng.range(-5.0, 20.0) as f32);
            let d =
                v3(rng.range(-1.0, 1.0) as f32, rng.range(-1.0, 1.0) as f32, rng.range(-1.0, 1.0) as f32).normalize();
            let mut brute = f32::INFINITY;
            let inv = v3(1.0 / d.x, 1.0 / d.y, 1.0 / d.z);
            for b in &boxes {
                if let Some(t) = b.hit(o, inv, f32::INFINITY) {
                    brute = brute.min(t);
                }
            }
            let mut ray = Ray::new(o, d);
            bvh.traverse(&mut ray, false, |p, tmax| boxes[p as usize].hit(o, inv, tmax));
            assert_eq!(ray.tmax, brute);
        }
    }
}
