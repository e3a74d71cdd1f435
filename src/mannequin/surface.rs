//! Polygonising the implicit body: sample it on a grid, extract a closed quad mesh with naive
//! surface nets (one vertex per cell that the surface crosses, one quad per grid edge that it
//! crosses), split the quads, then Taubin-smooth the staircase away.
//!
//! Everything is a dense array indexed by grid coordinates, so the output depends on nothing
//! but the inputs: no hash maps, no threads.

use glam::{UVec3, Vec3};

/// Scalar samples of a field on a regular grid.
pub(super) struct Grid {
    origin: Vec3,
    cell: f32,
    dims: UVec3,
    values: Vec<f32>,
}

impl Grid {
    /// Samples `field` on the nodes `origin + cell * (i, j, k)` for `i < dims.x` etc.
    pub fn sample(origin: Vec3, cell: f32, dims: UVec3, field: impl Fn(Vec3) -> f32) -> Self {
        let mut values = Vec::with_capacity((dims.x * dims.y * dims.z) as usize);
        for k in 0..dims.z {
            for j in 0..dims.y {
                for i in 0..dims.x {
                    values.push(field(
                        origin + cell * Vec3::new(i as f32, j as f32, k as f32),
                    ));
                }
            }
        }
        Self {
            origin,
            cell,
            dims,
            values,
        }
    }

    fn node(&self, i: u32, j: u32, k: u32) -> usize {
        (i + self.dims.x * (j + self.dims.y * k)) as usize
    }

    fn position(&self, i: u32, j: u32, k: u32) -> Vec3 {
        self.origin + self.cell * Vec3::new(i as f32, j as f32, k as f32)
    }
}

/// Node offsets of a cell's eight corners, bit `b` of the corner number set when the corner is
/// one step along axis `b`.
const CORNERS: [[u32; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [0, 1, 0],
    [1, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [0, 1, 1],
    [1, 1, 1],
];

/// The twelve cell edges as corner pairs.
const CELL_EDGES: [[usize; 2]; 12] = [
    [0, 1],
    [2, 3],
    [4, 5],
    [6, 7],
    [0, 2],
    [1, 3],
    [4, 6],
    [5, 7],
    [0, 4],
    [1, 5],
    [2, 6],
    [3, 7],
];

/// True when a cell whose inside corners are the set bits of `mask` holds a single disk of
/// surface: its inside corners, and its outside corners, are each connected along the cell's
/// edges (or empty). Otherwise one cell vertex would join several sheets (an ambiguous face
/// makes an edge of four triangles; two diagonal corners make a pinched vertex).
fn single_patch(mask: u8) -> bool {
    let connected = |set: u8| {
        if set == 0 {
            return true;
        }
        let mut reached = 1u8 << set.trailing_zeros();
        loop {
            let mut next = reached;
            for [a, b] in CELL_EDGES {
                let (a, b) = (1u8 << a, 1u8 << b);
                if set & a != 0 && set & b != 0 && (reached & (a | b)) != 0 {
                    next |= a | b;
                }
            }
            if next == reached {
                return reached == set;
            }
            reached = next;
        }
    };
    connected(mask) && connected(!mask)
}

impl Grid {
    fn inside_mask(&self, i: u32, j: u32, k: u32) -> u8 {
        CORNERS
            .iter()
            .enumerate()
            .fold(0u8, |m, (c, &[di, dj, dk])| {
                m | (u8::from(self.values[self.node(i + di, j + dj, k + dk)] < 0.0) << c)
            })
    }

    /// Makes every cell a single patch (see [`single_patch`]) by moving the level set across
    /// the fewest, nearest nodes: in each bad cell, the corner closest to the surface whose
    /// flip mends the cell gets a tiny value of the other sign. Such cells occur where a saddle
    /// of the surface passes a cell face, even on a smooth body. Returns the number of nodes
    /// flipped, or `None` if some cell is still bad after a few sweeps.
    pub fn make_manifold(&mut self) -> Option<usize> {
        let table: [bool; 256] = std::array::from_fn(|m| single_patch(m as u8));
        let [nx, ny, nz] = self.dims.to_array();
        let tiny = 1e-6 * self.cell;
        let mut flipped = 0;
        for _ in 0..8 {
            let mut bad = 0;
            for k in 0..nz - 1 {
                for j in 0..ny - 1 {
                    for i in 0..nx - 1 {
                        let mask = self.inside_mask(i, j, k);
                        if table[mask as usize] {
                            continue;
                        }
                        bad += 1;
                        let fix = (0..8)
                            .filter(|&c| table[(mask ^ (1 << c)) as usize])
                            .min_by(|&a, &b| {
                                let value = |c: usize| {
                                    let [di, dj, dk] = CORNERS[c];
                                    self.values[self.node(i + di, j + dj, k + dk)].abs()
                                };
                                value(a).total_cmp(&value(b))
                            });
                        if let Some(c) = fix {
                            let [di, dj, dk] = CORNERS[c];
                            let n = self.node(i + di, j + dj, k + dk);
                            self.values[n] = if self.values[n] < 0.0 { tiny } else { -tiny };
                            flipped += 1;
                        }
                    }
                }
            }
            if bad == 0 {
                return Some(flipped);
            }
        }
        None
    }
}

/// Surface nets on `grid`'s zero level set (inside where negative). Returns positions and a
/// counter-clockwise (outward-facing) triangle list. Every node on the grid's boundary must be
/// outside, so that the surface is closed.
pub(super) fn surface_nets(grid: &Grid) -> (Vec<Vec3>, Vec<u32>) {
    let [nx, ny, nz] = grid.dims.to_array();
    let inside = |i: u32, j: u32, k: u32| grid.values[grid.node(i, j, k)] < 0.0;

    // One vertex per crossed cell, at the mean of its edge crossings.
    let cell_index = |i: u32, j: u32, k: u32| (i + (nx - 1) * (j + (ny - 1) * k)) as usize;
    let mut vertex_of_cell = vec![u32::MAX; ((nx - 1) * (ny - 1) * (nz - 1)) as usize];
    let mut positions = Vec::new();
    for k in 0..nz - 1 {
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let corner = CORNERS.map(|[di, dj, dk]| grid.node(i + di, j + dj, k + dk));
                let value = corner.map(|n| grid.values[n]);
                let mask = value
                    .iter()
                    .enumerate()
                    .fold(0u8, |m, (c, &v)| m | (u8::from(v < 0.0) << c));
                if mask == 0 || mask == 0xff {
                    continue;
                }
                let mut sum = Vec3::ZERO;
                let mut count = 0.0;
                for [a, b] in CELL_EDGES {
                    let (va, vb) = (value[a], value[b]);
                    if (va < 0.0) == (vb < 0.0) {
                        continue;
                    }
                    let t = (va / (va - vb)).clamp(0.0, 1.0);
                    let pa = Vec3::from_array(CORNERS[a].map(|c| c as f32));
                    let pb = Vec3::from_array(CORNERS[b].map(|c| c as f32));
                    sum += pa + t * (pb - pa);
                    count += 1.0;
                }
                vertex_of_cell[cell_index(i, j, k)] = positions.len() as u32;
                positions.push(grid.position(i, j, k) + grid.cell * sum / count);
            }
        }
    }

    // One quad per crossed grid edge, joining the four cells around it.
    let mut indices = Vec::new();
    let mut quad = |cells: [(u32, u32, u32); 4], flip: bool, positions: &[Vec3]| {
        let mut v = cells.map(|(i, j, k)| vertex_of_cell[cell_index(i, j, k)]);
        debug_assert!(v.iter().all(|&x| x != u32::MAX));
        if flip {
            v.reverse();
        }
        let p = v.map(|x| positions[x as usize]);
        // Split along the shorter diagonal.
        if p[0].distance_squared(p[2]) <= p[1].distance_squared(p[3]) {
            indices.extend_from_slice(&[v[0], v[1], v[2], v[0], v[2], v[3]]);
        } else {
            indices.extend_from_slice(&[v[0], v[1], v[3], v[1], v[2], v[3]]);
        }
    };
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let here = inside(i, j, k);
                // Edges along x: cells around it lie in the (y, z) plane, counter-clockwise about
                // +x; the surface faces +x when the near end is inside.
                if i + 1 < nx && j >= 1 && k >= 1 && j < ny - 1 && k < nz - 1 {
                    let there = inside(i + 1, j, k);
                    if here != there {
                        let cells = [(i, j - 1, k - 1), (i, j, k - 1), (i, j, k), (i, j - 1, k)];
                        quad(cells, !here, &positions);
                    }
                }
                // Along y: the (z, x) plane, counter-clockwise about +y.
                if j + 1 < ny && i >= 1 && k >= 1 && i < nx - 1 && k < nz - 1 {
                    let there = inside(i, j + 1, k);
                    if here != there {
                        let cells = [(i - 1, j, k - 1), (i - 1, j, k), (i, j, k), (i, j, k - 1)];
                        quad(cells, !here, &positions);
                    }
                }
                // Along z: the (x, y) plane, counter-clockwise about +z.
                if k + 1 < nz && i >= 1 && j >= 1 && i < nx - 1 && j < ny - 1 {
                    let there = inside(i, j, k + 1);
                    if here != there {
                        let cells = [(i - 1, j - 1, k), (i, j - 1, k), (i, j, k), (i - 1, j, k)];
                        quad(cells, !here, &positions);
                    }
                }
            }
        }
    }
    (positions, indices)
}

/// Vertex neighbours (unique, ascending) in compressed rows: the neighbours of `v` are
/// `neighbours[offsets[v]..offsets[v + 1]]`.
pub(super) struct Adjacency {
    pub offsets: Vec<u32>,
    pub neighbours: Vec<u32>,
}

impl Adjacency {
    pub fn new(vertex_count: usize, indices: &[u32]) -> Self {
        let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(indices.len() * 2);
        for t in indices.chunks_exact(3) {
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                pairs.push((a, b));
                pairs.push((b, a));
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        let mut offsets = vec![0u32; vertex_count + 1];
        for &(a, _) in &pairs {
            offsets[a as usize + 1] += 1;
        }
        for v in 0..vertex_count {
            offsets[v + 1] += offsets[v];
        }
        Self {
            offsets,
            neighbours: pairs.into_iter().map(|(_, b)| b).collect(),
        }
    }

    pub fn of(&self, v: usize) -> &[u32] {
        &self.neighbours[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }
}

/// Taubin's lambda|mu smoothing (1995): a shrinking Laplacian step followed by an inflating
/// one, which removes the grid's staircase without the shrinkage of plain Laplacian smoothing.
pub(super) fn taubin(positions: &mut [Vec3], adjacency: &Adjacency, iterations: usize) {
    const LAMBDA: f32 = 0.5;
    const MU: f32 = -0.53;
    let mut next = positions.to_vec();
    for _ in 0..iterations {
        for factor in [LAMBDA, MU] {
            for (v, out) in next.iter_mut().enumerate() {
                let ring = adjacency.of(v);
                let mean = ring.iter().map(|&n| positions[n as usize]).sum::<Vec3>()
                    / ring.len().max(1) as f32;
                *out = positions[v] + factor * (mean - positions[v]);
            }
            positions.copy_from_slice(&next);
        }
    }
}

/// Area-weighted vertex normals.
pub(super) fn vertex_normals(positions: &[Vec3], indices: &[u32]) -> Vec<Vec3> {
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| positions[i as usize]);
        let n = (b - a).cross(c - a);
        for &i in t {
            normals[i as usize] += n;
        }
    }
    normals
        .into_iter()
        .map(|n| n.try_normalize().unwrap_or(Vec3::Y))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_patch_rejects_ambiguous_cells() {
        assert!(single_patch(0) && single_patch(0xff) && single_patch(0b1));
        assert!(single_patch(0b1111), "a face inside");
        assert!(!single_patch(0b1001), "diagonal corners of a face");
        assert!(!single_patch(0b1000_0001), "opposite corners of the cell");
        assert!(!single_patch(!0b1000_0001), "their complement");
    }

    /// Two inside nodes on the diagonal of a cell face: unmended, the cells on either side of
    /// the face share an edge of four triangles.
    #[test]
    fn mended_grid_gives_a_manifold() {
        let field = |p: Vec3| {
            let inside = [Vec3::new(2.0, 2.0, 2.0), Vec3::new(3.0, 3.0, 2.0)];
            if inside.contains(&p) { -0.5 } else { 0.5 }
        };
        let oriented_edges = |grid: &Grid| {
            let (_, indices) = surface_nets(grid);
            let mut edges: Vec<(u32, u32)> = indices
                .chunks_exact(3)
                .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
                .collect();
            edges.sort_unstable();
            edges
        };
        let mut grid = Grid::sample(Vec3::ZERO, 1.0, UVec3::splat(6), field);
        let edges = oriented_edges(&grid);
        assert!(
            edges.windows(2).any(|w| w[0] == w[1]),
            "ambiguous before mending"
        );

        assert_eq!(grid.make_manifold(), Some(1));
        let edges = oriented_edges(&grid);
        for w in edges.windows(2) {
            assert_ne!(w[0], w[1], "an oriented edge is used twice");
        }
        for &(a, b) in &edges {
            assert!(edges.binary_search(&(b, a)).is_ok(), "edge {a}-{b} is open");
        }
    }

    /// A sphere polygonises into a closed mesh whose triangles face outwards.
    #[test]
    fn sphere_is_closed_and_outward() {
        let grid = Grid::sample(Vec3::splat(-1.2), 0.1, UVec3::splat(25), |p| {
            p.length() - 0.8
        });
        let (positions, indices) = surface_nets(&grid);
        let mut edges: Vec<(u32, u32)> = indices
            .chunks_exact(3)
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .collect();
        edges.sort_unstable();
        for w in edges.windows(2) {
            assert_ne!(w[0], w[1], "an oriented edge is used twice");
        }
        for &(a, b) in &edges {
            assert!(edges.binary_search(&(b, a)).is_ok(), "edge {a}-{b} is open");
        }
        let volume: f32 = indices
            .chunks_exact(3)
            .map(|t| {
                let [a, b, c] = [t[0], t[1], t[2]].map(|i| positions[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum();
        let exact = 4.0 / 3.0 * std::f32::consts::PI * 0.8f32.powi(3);
        assert!((volume - exact).abs() < 0.05 * exact, "{volume} vs {exact}");
    }
}
