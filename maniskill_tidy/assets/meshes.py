"""Source meshes -> the package's meshes: our frame, a triangle budget that keeps UVs, GLB.

Software rendering pays per triangle (about 0.3 ms per 1000 for three cameras on lavapipe), so
every model is decimated to a budget. Quadric decimation (open3d) moves vertices and forgets
UVs; each new face gets them back from the original face nearest its centroid: the corners'
barycentric coordinates on that face's plane interpolate its UVs and normals. Faces therefore
keep their own three vertices, so a face never straddles a texture seam.
"""

from __future__ import annotations

import io

import numpy as np
import open3d as o3d
import trimesh
from PIL import Image

# OBJ (Sweet Home 3D): y up, the front faces +z. Ours: z up, the front faces +y. A proper
# rotation (no mirror): x -> -x, z -> y, y -> z.
SH3D_TO_OURS = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
MIN_OPACITY = 0.6  # see-through parts (glass) render black with the minimal shader: dropped


def load_obj(path, rotation: np.ndarray) -> list[tuple[trimesh.Trimesh, dict]]:
    """The OBJ's parts in our frame (source units), each with its material's look."""
    scene = trimesh.load(str(path), force="scene", process=False)
    frame = SH3D_TO_OURS @ rotation
    parts = []
    for name in sorted(scene.geometry):
        mesh = scene.geometry[name]
        if len(mesh.faces) == 0:
            continue
        material = getattr(mesh.visual, "material", None)
        look = material_look(material)
        if look["opacity"] < MIN_OPACITY:
            continue
        uv = getattr(mesh.visual, "uv", None)
        if uv is None or len(uv) != len(mesh.vertices) or look["image"] is None:
            uv, look["image"] = None, None
        normals = mesh.vertex_normals  # from the file's vn, or computed
        m = trimesh.Trimesh(
            vertices=mesh.vertices @ frame.T,
            faces=mesh.faces,
            vertex_normals=normals @ frame.T,
            process=False,
        )
        parts.append((m, look | {"uv": None if uv is None else np.asarray(uv, np.float64)}))
    return parts


def material_look(material) -> dict:
    """Colour, texture and opacity of a trimesh material (an MTL's Kd, map_Kd, d)."""
    colour = np.array([200, 200, 200, 255], dtype=np.float64)
    image, opacity = None, 1.0
    if material is not None:
        if getattr(material, "diffuse", None) is not None:
            colour = np.asarray(material.diffuse, dtype=np.float64)
        image = getattr(material, "image", None)
        d = (getattr(material, "kwargs", None) or {}).get("d")
        if d:
            opacity = float(d[0] if isinstance(d, (list, tuple)) else d)
    return {"colour": colour[:3] / 255.0, "image": image, "opacity": opacity}


def decimate(
    mesh: trimesh.Trimesh, uv: np.ndarray | None, target: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(corners (n, 3, 3), normals (n, 3, 3), uvs (n, 3, 2) or None) of at most ``target`` faces."""
    verts = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    normals = np.asarray(mesh.vertex_normals, dtype=np.float64)
    if len(faces) <= target:
        corners = verts[faces]
        return corners, *finite(corners, normals[faces], None if uv is None else uv[faces])
    o3 = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(verts), o3d.utility.Vector3iVector(faces.astype(np.int32))
    )
    simple = reduce(o3.remove_duplicated_vertices(), int(target))
    new_v = np.asarray(simple.vertices)
    new_f = np.asarray(simple.triangles, dtype=np.int64)
    corners = new_v[new_f]  # (n, 3, 3)
    if len(corners) == 0:
        return corners, corners.copy(), None if uv is None else np.zeros((0, 3, 2))
    caster = o3d.t.geometry.RaycastingScene()
    caster.add_triangles(
        o3d.core.Tensor(verts.astype(np.float32)), o3d.core.Tensor(faces.astype(np.uint32))
    )
    hit = caster.compute_closest_points(o3d.core.Tensor(corners.mean(1).astype(np.float32)))
    nearest = faces[hit["primitive_ids"].numpy().astype(np.int64)]  # (n, 3) original corners
    tri = np.repeat(verts[nearest], 3, axis=0)  # each new corner against its face's original
    bary = trimesh.triangles.points_to_barycentric(tri, corners.reshape(-1, 3))
    bary = bary.reshape(-1, 3, 3)  # (n faces, 3 corners, 3 weights)
    n = np.einsum("fck,fkd->fcd", bary, normals[nearest])
    n /= np.maximum(np.linalg.norm(n, axis=2, keepdims=True), 1e-9)
    uvs = None if uv is None else np.einsum("fck,fkd->fcd", bary, uv[nearest])
    return corners, *finite(corners, n, uvs)


def finite(corners, normals, uvs):
    """Degenerate source faces give NaN weights: use the face's own normal, UV (0, 0) there."""
    face = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    face /= np.maximum(np.linalg.norm(face, axis=1, keepdims=True), 1e-12)
    bad = ~np.isfinite(normals).all(axis=2) | (np.linalg.norm(normals, axis=2) < 0.5)
    normals = np.where(bad[..., None], face[:, None, :], normals)
    if uvs is not None:
        uvs = np.where(np.isfinite(uvs), uvs, 0.0)
    return normals, uvs


def reduce(mesh: o3d.geometry.TriangleMesh, target: int) -> o3d.geometry.TriangleMesh:
    """Quadric decimation to ``target`` faces. A part made of many small closed pieces (knobs,
    screws) cannot get below a few faces per piece, so then nearby vertices are first merged on
    a grid that grows until quadric decimation reaches the budget."""
    extent = float(np.max(mesh.get_max_bound() - mesh.get_min_bound()))
    voxel = extent / 256
    simple = mesh.simplify_quadric_decimation(target)
    while len(simple.triangles) > 1.1 * target and voxel < extent / 4:
        clustered = mesh.simplify_vertex_clustering(voxel)
        simple = clustered.simplify_quadric_decimation(target)
        voxel *= 1.5
    return simple.remove_degenerate_triangles().remove_unreferenced_vertices()


def downscale(image: Image.Image, max_side: int) -> Image.Image:
    image = image.convert("RGB")
    scale = max_side / max(image.size)
    if scale < 1:
        size = tuple(max(4, round(s * scale)) for s in image.size)
        image = image.resize(size, Image.Resampling.LANCZOS)
    return image


def part_mesh(corners, normals, uvs, look: dict, max_texture: int) -> trimesh.Trimesh:
    """One material's faces as a trimesh with a PBR material glTF can carry. The renderer culls
    back faces, so each face is wound to agree with its normals (a mirrored source transform
    would otherwise leave a part invisible from outside)."""
    n = len(corners)
    geometric = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    flip = np.einsum("fd,fd->f", geometric, normals.mean(axis=1)) < 0
    corners, normals = corners.copy(), normals.copy()
    corners[flip], normals[flip] = corners[flip][:, ::-1], normals[flip][:, ::-1]
    if uvs is not None:
        uvs = uvs.copy()
        uvs[flip] = uvs[flip][:, ::-1]
    kwargs = {
        "roughnessFactor": look.get("roughness", 0.7),
        "metallicFactor": look.get("metallic", 0.0),
    }
    if uvs is not None and look["image"] is not None:
        material = trimesh.visual.material.PBRMaterial(
            baseColorTexture=downscale(look["image"], max_texture), **kwargs
        )
        visual = trimesh.visual.TextureVisuals(uv=uvs.reshape(-1, 2), material=material)
    else:
        rgba = np.append(np.clip(look["colour"], 0, 1), 1.0)
        material = trimesh.visual.material.PBRMaterial(
            baseColorFactor=(rgba * 255).round().astype(np.uint8), **kwargs
        )
        visual = trimesh.visual.TextureVisuals(material=material)
    return trimesh.Trimesh(
        vertices=corners.reshape(-1, 3),
        faces=np.arange(3 * n).reshape(n, 3),
        vertex_normals=normals.reshape(-1, 3),
        visual=visual,
        process=False,
    )


def budget_split(counts: list[int], budget: int, floor: int = 12) -> list[int]:
    """Triangles per part: proportional to its count, never more than it has."""
    total = sum(counts)
    if total <= budget:
        return list(counts)
    return [min(c, max(floor, int(budget * c / total))) for c in counts]


def glb_bytes(meshes: list[trimesh.Trimesh]) -> bytes:
    scene = trimesh.Scene()
    for i, m in enumerate(meshes):
        scene.add_geometry(m, geom_name=f"part_{i:02d}", node_name=f"part_{i:02d}")
    return scene.export(file_type="glb", include_normals=True)


def image_png(image: Image.Image) -> bytes:
    buf = io.BytesIO()
    image.save(buf, format="PNG", optimize=False, compress_level=9)
    return buf.getvalue()
