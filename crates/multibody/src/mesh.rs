//! Collision meshes of a URDF (`<mesh filename="..." scale="..."/>`): an STL (binary or ASCII) or OBJ file,
//! read bounded, scaled, and reduced to its convex hull, which is what the contact solver takes (a convex
//! shape: one contact manifold per pair, no tunnelling through a thin triangle soup). A concave part is
//! given as several `<collision>` elements, each convex. A `<visual>` mesh is kept as its triangles, for
//! viewers.

use std::path::{Path, PathBuf};

use rapier3d_f64::math::Vector;

/// A mesh's convex hull in the link frame: its vertices (m) and outward triangles (indices into them).
#[derive(Debug, Clone, PartialEq)]
pub struct ConvexHull {
    /// Hull vertices, m, in the collision element's frame (scaled).
    pub vertices: Vec<[f64; 3]>,
    /// Triangles of the hull surface, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

/// A mesh as its file gives it, scaled: vertices (m) and triangles (indices into them). What a URDF's
/// `<visual>` mesh draws.
#[derive(Debug, Clone, PartialEq)]
pub struct TriangleMesh {
    /// Vertices, m, in the visual element's frame (scaled).
    pub vertices: Vec<[f64; 3]>,
    /// Triangles as the file orders them.
    pub triangles: Vec<[u32; 3]>,
}

/// Where the mesh named by a URDF's `filename` is: relative to the URDF's folder, absolute, or `file://`.
/// `package://` needs a ROS package index this tool does not have: refused, with the fix.
pub fn resolve(urdf: &Path, filename: &str) -> Result<PathBuf, String> {
    if filename.starts_with("package://") {
        return Err(format!(
            "mesh '{filename}': package:// paths need a ROS package index; give the path relative to the URDF's folder"
        ));
    }
    let name = filename.strip_prefix("file://").unwrap_or(filename);
    let p = Path::new(name);
    Ok(if p.is_absolute() {
        p.to_path_buf()
    } else {
        urdf.parent().unwrap_or_else(|| Path::new("")).join(p)
    })
}

/// The vertices of the STL or OBJ file at `path` (by its extension), each multiplied by `scale`.
pub fn read_vertices(path: &Path, scale: [f64; 3]) -> Result<Vec<[f64; 3]>, String> {
    read_mesh(path, scale).map(|m| m.vertices)
}

/// The STL or OBJ file at `path` (by its extension), its vertices multiplied by `scale`.
pub fn read_mesh(path: &Path, scale: [f64; 3]) -> Result<TriangleMesh, String> {
    let bytes = pneuflex_files::read_bytes(path, pneuflex_files::InputKind::Mesh)
        .map_err(|e| e.to_string())?;
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let index =
        |i: usize| u32::try_from(i).map_err(|_| format!("{}: too many vertices", path.display()));
    let (raw, triangles): (Vec<[f64; 3]>, Vec<[u32; 3]>) = match ext.as_str() {
        // STL stores single precision; the hull is formed in f64 from those values.
        "stl" => {
            let mesh = stl_io::read_stl(&mut std::io::Cursor::new(&bytes))
                .map_err(|e| format!("{}: not a readable STL file: {e}", path.display()))?;
            let triangles = mesh
                .faces
                .iter()
                .map(|f| {
                    Ok([
                        index(f.vertices[0])?,
                        index(f.vertices[1])?,
                        index(f.vertices[2])?,
                    ])
                })
                .collect::<Result<_, String>>()?;
            let vertices = mesh
                .vertices
                .iter()
                .map(|v| [f64::from(v[0]), f64::from(v[1]), f64::from(v[2])])
                .collect();
            (vertices, triangles)
        }
        "obj" => {
            let options = tobj::LoadOptions {
                triangulate: true,
                single_index: true,
                ..Default::default()
            };
            // Materials do not matter for contact: a missing .mtl is no error.
            let (models, _) =
                tobj::load_obj_buf(&mut bytes.as_slice(), &options, |_| Ok(Default::default()))
                    .map_err(|e| format!("{}: not a readable OBJ file: {e}", path.display()))?;
            let mut vertices = Vec::new();
            let mut triangles = Vec::new();
            for m in &models {
                let base = index(vertices.len())?;
                vertices.extend(m.mesh.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
                triangles.extend(
                    m.mesh
                        .indices
                        .chunks_exact(3)
                        .map(|t| [base + t[0], base + t[1], base + t[2]]),
                );
            }
            (vertices, triangles)
        }
        _ => {
            return Err(format!(
                "{}: a mesh must be .stl or .obj, not '.{ext}'",
                path.display()
            ));
        }
    };
    if let Some(v) = raw.iter().find(|v| v.iter().any(|c| !c.is_finite())) {
        return Err(format!("{}: a vertex is not finite: {v:?}", path.display()));
    }
    if let Some(t) = triangles
        .iter()
        .find(|t| t.iter().any(|&i| i as usize >= raw.len()))
    {
        return Err(format!(
            "{}: triangle {t:?} names a vertex past the {} there are",
            path.display(),
            raw.len()
        ));
    }
    Ok(TriangleMesh {
        vertices: raw
            .iter()
            .map(|v| [v[0] * scale[0], v[1] * scale[1], v[2] * scale[2]])
            .collect(),
        triangles,
    })
}

/// The convex hull of `points`; an error when they span no volume (fewer than 4 points, or all on a plane or
/// a line): such a mesh cannot take contact as a solid.
pub fn convex_hull(points: &[[f64; 3]]) -> Result<ConvexHull, String> {
    let pts: Vec<Vector> = points
        .iter()
        .map(|p| Vector::new(p[0], p[1], p[2]))
        .collect();
    let (vertices, triangles) = rapier3d_f64::parry::transformation::try_convex_hull(&pts)
        .map_err(|e| {
            format!(
                "its convex hull cannot be built ({e:?}) from {} vertices",
                points.len()
            )
        })?;
    let hull = ConvexHull {
        vertices: vertices.iter().map(|v| [v.x, v.y, v.z]).collect(),
        triangles,
    };
    if hull.volume() <= 0.0 || !hull.volume().is_finite() {
        return Err(format!(
            "its {} vertices span no volume (flat or a line): a collision mesh must be a solid",
            points.len()
        ));
    }
    if hull.builder().is_none() {
        return Err(format!(
            "parry makes no convex collider of its hull ({} vertices)",
            hull.vertices.len()
        ));
    }
    Ok(hull)
}

impl ConvexHull {
    /// The collider of the hull: its vertices and faces as a convex polyhedron (or, where parry finds the
    /// faces not convex to its tolerance, the hull of the vertices again); `None` if neither is.
    fn builder(&self) -> Option<rapier3d_f64::prelude::ColliderBuilder> {
        use rapier3d_f64::prelude::ColliderBuilder;
        let points: Vec<Vector> = self
            .vertices
            .iter()
            .map(|p| Vector::new(p[0], p[1], p[2]))
            .collect();
        ColliderBuilder::convex_mesh(points.clone(), &self.triangles)
            .or_else(|| ColliderBuilder::convex_hull(&points))
    }

    /// [`Self::builder`] of a hull that [`convex_hull`] returned, which checked that there is one.
    pub(crate) fn collider(&self) -> rapier3d_f64::prelude::ColliderBuilder {
        self.builder()
            .expect("convex_hull returns only hulls that make a collider")
    }

    /// Enclosed volume, m^3 (the divergence theorem over the outward triangles).
    pub fn volume(&self) -> f64 {
        let v = &self.vertices;
        self.triangles
            .iter()
            .map(|t| {
                let (a, b, c) = (v[t[0] as usize], v[t[1] as usize], v[t[2] as usize]);
                // a . (b x c) / 6 for each face.
                (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                    + a[2] * (b[0] * c[1] - b[1] * c[0]))
                    / 6.0
            })
            .sum()
    }

    /// Half extents and centre of the hull's axis-aligned bounding box, m.
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for v in &self.vertices {
            for i in 0..3 {
                lo[i] = lo[i].min(v[i]);
                hi[i] = hi[i].max(v[i]);
            }
        }
        (
            std::array::from_fn(|i| 0.5 * (hi[i] - lo[i])),
            std::array::from_fn(|i| 0.5 * (hi[i] + lo[i])),
        )
    }
}
