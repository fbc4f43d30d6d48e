"""Objects out of the non-plane points: instance labels, scribbles + GrabCut, or clustering.

Priority: per-point instance ids from the input (``instance.png``, PCD ``label``) are
used as they are; scribbled objects are cut out of the colour-and-depth image by
GrabCut; whatever is left is clustered by proximity (Open3D DBSCAN on a voxel grid).
Clusters of a depth image are then split where objects part in depth data
(:func:`split_clusters`): depth steps and concave creases.
"""

from __future__ import annotations

import numpy as np

#: An object named by an instance mask needs only this many points (clusters need more;
#: :func:`pipeline.initial.initial_cuboids` fits a box to as few).  A wall-shelf bracket
#: under its board or a book between two others, 5 m away, shows 10-29 (a part glimpsed
#: at its foot is then completed by the object's other parts).  Below 10, a speck of a
#: cushion's edge made a box of its own (sofa-1003 of Table 1 100 -> 71 at 5).
MIN_INSTANCE_POINTS = 10

#: Depth jump, relative to depth, that marks a pixel as a flying pixel at an edge.
FLYING_REL_JUMP = 0.04


def flying_pixels(depth: np.ndarray, rel: float = FLYING_REL_JUMP) -> np.ndarray:
    """(H, W) bool: pixels whose depth jumps by more than ``rel * depth`` to both sides
    along a row or a column (mixed pixels at silhouettes), or next to a hole."""
    d = np.asarray(depth, float)
    pad = np.pad(d, 1, mode="edge")
    c = pad[1:-1, 1:-1]
    thr = rel * np.maximum(c, 1e-6)
    left, right = pad[1:-1, :-2], pad[1:-1, 2:]
    up, down = pad[:-2, 1:-1], pad[2:, 1:-1]
    jump_h = (np.abs(c - left) > thr) & (np.abs(c - right) > thr)
    jump_v = (np.abs(c - up) > thr) & (np.abs(c - down) > thr)
    return (jump_h | jump_v) & (c > 0)


def voxel_keys(points: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Voxel-grid the points: (representative mean per voxel (m, 3), inverse (n,))."""
    key = np.floor((points - points.min(0)) / cell).astype(np.int64)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.ravel()
    m = int(inv.max()) + 1
    cnt = np.bincount(inv, minlength=m).astype(float)
    rep = np.stack([np.bincount(inv, points[:, k], minlength=m) for k in range(3)], 1) / cnt[:, None]
    return rep, inv


def point_spacing(points: np.ndarray, rng_seed: int = 0, sample: int = 5000) -> float:
    """Median nearest-neighbour distance of ``points (n, 3)`` (on a fixed subsample)."""
    from scipy.spatial import cKDTree

    if len(points) < 3:
        return 0.0
    idx = np.random.default_rng(rng_seed).choice(len(points), min(sample, len(points)), replace=False)
    d, _ = cKDTree(points).query(points[np.sort(idx)], k=2)
    return float(np.median(d[:, 1]))


def cluster(points: np.ndarray, cell: float, eps_cells: float = 2.6,
            min_voxels: int = 3) -> np.ndarray:
    """Proximity clusters of ``points (n, 3)``: (n,) int labels 0..K-1, -1 noise.

    Points are gridded at ``cell``; Open3D DBSCAN with ``eps = eps_cells * cell`` runs on
    the voxel means and the labels go back to every point.
    """
    import open3d as o3d

    if len(points) == 0:
        return np.zeros(0, dtype=np.int64)
    rep, inv = voxel_keys(points, cell)
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(rep))
    lab = np.asarray(pc.cluster_dbscan(eps=eps_cells * cell, min_points=min_voxels), dtype=np.int64)
    lab = _canonical(lab)
    return lab[inv]


def _canonical(lab: np.ndarray) -> np.ndarray:
    """Relabel clusters by decreasing size (ties by first index) so output is deterministic."""
    valid = lab >= 0
    if not valid.any():
        return lab
    ids, first, counts = np.unique(lab[valid], return_index=True, return_counts=True)
    order = np.lexsort((first, -counts))
    remap = np.full(int(ids.max()) + 1, -1, dtype=np.int64)
    remap[ids[order]] = np.arange(len(ids))
    out = lab.copy()
    out[valid] = remap[lab[valid]]
    return out


#: Pixels of one mask this far apart (pixels, in rows and columns) are neighbours in
#: :func:`image_components`: the sensor drops pixels of a surface seen at a grazing angle.
MASK_LINK_PX = 2


def image_components(pixels: np.ndarray, depth: np.ndarray,
                     rel: float = FLYING_REL_JUMP, radius: int = MASK_LINK_PX) -> np.ndarray:
    """(n,) int: components of the pixels ``(n, 2)`` (row, column) with readings
    ``depth (n,)`` that the image links through surface steps.

    Two pixels within ``radius`` of each other are linked when their depths differ by at
    most ``rel`` of the larger one: a surface seen at any angle the sensor measures
    steps less than that across a dropped pixel or two, while a larger step is a
    silhouette (:func:`flying_pixels` uses the same jump).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(pixels)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    v, u = pixels[:, 0].astype(np.int64), pixels[:, 1].astype(np.int64)
    v0, u0 = v.min(), u.min()
    H, W = int(v.max() - v0) + 1, int(u.max() - u0) + 1
    index = np.full((H + 2 * radius, W + 2 * radius), -1, dtype=np.int64)
    index[v - v0 + radius, u - u0 + radius] = np.arange(n)
    d = np.asarray(depth, float)
    rows, cols = [], []
    for dv in range(0, radius + 1):
        for du in range(-radius, radius + 1):
            if (dv, du) <= (0, 0):
                continue
            j = index[v - v0 + radius + dv, u - u0 + radius + du]
            ok = j >= 0
            i, j = np.nonzero(ok)[0], j[ok]
            near = np.abs(d[i] - d[j]) <= rel * np.maximum(d[i], d[j])
            rows.append(i[near])
            cols.append(j[near])
    r, c = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(r), dtype=np.int8), (r, c)), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def _main_components(world: np.ndarray, sel: np.ndarray, cell: float,
                     keep_share: float = 0.05, pixels: np.ndarray | None = None,
                     depth: np.ndarray | None = None) -> np.ndarray:
    """Drop stray points of a mask (mislabelled edge pixels): keep the proximity clusters
    holding at least ``keep_share`` of the largest one.

    With the mask's ``pixels (n, 2)`` and their ``depth (n,)`` readings, a smaller
    cluster that the image links to a kept one through surface steps
    (:func:`image_components`) is kept too.  A depth sensor's noise and quantization
    grow with the square of the distance, and it drops pixels of a surface seen at a
    grazing angle: such a surface comes as layers and specks along the rays that
    proximity alone takes apart (a sofa's seat seen along its length, a table leg 4 m
    away read at three depths 6 cm apart), while a stray edge pixel lies a silhouette's
    step behind its object.  A lone point (proximity noise) stays out even when the
    image links it: one reading off along its ray stretches a box.
    """
    idx = np.nonzero(sel)[0]
    lab = cluster(world[idx], cell)
    if not (lab >= 0).any():
        return sel
    counts = np.bincount(lab[lab >= 0])
    good = np.nonzero(counts >= keep_share * counts.max())[0]
    keep = np.isin(lab, good)
    if pixels is not None and depth is not None and not keep.all():
        comp = image_components(pixels[idx], depth[idx])
        keep |= np.isin(comp, np.unique(comp[keep])) & (lab >= 0)
    out = np.zeros_like(sel)
    out[idx[keep]] = True
    return out


def depth_augmented(image: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8: colour with a third of each channel replaced by normalised depth,
    so GrabCut's colour models also see depth steps."""
    d = np.asarray(depth, float)
    valid = d > 0
    if valid.any():
        lo, hi = np.percentile(d[valid], [1, 99])
        dn = np.clip((d - lo) / max(hi - lo, 1e-6), 0, 1) * 255
    else:
        dn = np.zeros_like(d)
    return (image.astype(float) * (2 / 3) + dn[:, :, None] / 3).astype(np.uint8)


def grabcut_scribbles(image: np.ndarray, depth: np.ndarray, scribbles: np.ndarray,
                      allowed: np.ndarray, iterations: int = 4) -> np.ndarray:
    """Split touching objects from user strokes.

    Parameters
    ----------
    image : (H, W, 3) uint8 RGB
    depth : (H, W) float, metres
    scribbles : (H, W) int, stroke id per pixel (0 = none)
    allowed : (H, W) bool, pixels that may belong to an object (not a plane, valid depth)

    Returns
    -------
    labels : (H, W) int, the stroke id owning each pixel (0 = none)
    """
    import cv2

    aug = cv2.cvtColor(depth_augmented(image, depth), cv2.COLOR_RGB2BGR)
    ids = [int(i) for i in np.unique(scribbles) if i != 0]
    out = np.zeros(scribbles.shape, dtype=np.int64)
    prob = np.zeros(scribbles.shape, dtype=float)
    for k in ids:
        mask = np.where(allowed, cv2.GC_PR_BGD, cv2.GC_BGD).astype(np.uint8)
        mine = scribbles == k
        near = cv2.dilate(mine.astype(np.uint8), np.ones((41, 41), np.uint8)) > 0
        mask[near & allowed] = cv2.GC_PR_FGD
        mask[(scribbles != 0) & ~mine] = cv2.GC_BGD
        mask[mine] = cv2.GC_FGD
        bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
        cv2.grabCut(aug, mask, None, bgd, fgd, iterations, cv2.GC_INIT_WITH_MASK)
        fg = (mask == cv2.GC_FGD) | (mask == cv2.GC_PR_FGD)
        # keep the connected part that holds the stroke
        n, comp = cv2.connectedComponents(fg.astype(np.uint8), connectivity=8)
        keep = np.unique(comp[mine & fg])
        fg &= np.isin(comp, keep[keep > 0])
        dist = cv2.distanceTransform(fg.astype(np.uint8), cv2.DIST_L2, 3)
        take = fg & (dist > prob)
        out[take] = k
        prob[take] = dist[take]
    return out


def segment_objects(world: np.ndarray, object_mask: np.ndarray, cell: float, *,
                    instance: np.ndarray | None = None,
                    pixels: np.ndarray | None = None,
                    scribble_labels: np.ndarray | None = None,
                    min_points: int = 30,
                    depth: np.ndarray | None = None) -> tuple[np.ndarray, list[str]]:
    """Assign every object point an object index.

    Parameters
    ----------
    world : (n, 3) float
    object_mask : (n,) bool, points that may belong to objects (not planes, not flying)
    cell : float, voxel size for clustering
    instance : (n,) int or None, given ids (0 = none)
    pixels : (n, 2) int or None, (v, u) per point (for scribble labels)
    scribble_labels : (H, W) int or None, GrabCut output
    depth : (n,) float or None, each point's depth reading (with ``pixels``: a mask's
        points the image links to its main body stay, :func:`_main_components`)

    Returns
    -------
    labels : (n,) int, object index 0..K-1 or -1
    names : list of str, per object: ``inst<k>``, ``scribble<k>`` or ``cluster<k>``
    """
    n = len(world)
    labels = np.full(n, -1, dtype=np.int64)
    names: list[str] = []
    todo = object_mask.copy()
    if instance is not None and np.any(instance[object_mask] > 0):
        ids = np.unique(instance[object_mask & (instance > 0)])
        for i in ids:
            sel = object_mask & (instance == i)
            if sel.sum() >= min(min_points, MIN_INSTANCE_POINTS):  # given masks are trusted
                sel = _main_components(world, sel, cell, pixels=pixels, depth=depth)
                labels[sel] = len(names)
                names.append(f"inst{int(i)}")
        return labels, names
    if scribble_labels is not None and pixels is not None:
        sl = scribble_labels[pixels[:, 0], pixels[:, 1]]
        for i in np.unique(sl[object_mask & (sl > 0)]):
            sel = object_mask & (sl == i)
            if sel.sum() >= min_points:
                labels[sel] = len(names)
                names.append(f"scribble{int(i)}")
            todo &= ~sel
        # what GrabCut left next to a scribbled object belongs to it (grown 3 cells at most)
        if names and todo.any():
            from scipy.spatial import cKDTree

            owned = np.nonzero(labels >= 0)[0]
            tree = cKDTree(world[owned])
            for _ in range(3):
                idx = np.nonzero(todo)[0]
                if not len(idx):
                    break
                dist, nn = tree.query(world[idx], distance_upper_bound=1.5 * cell)
                near = np.isfinite(dist)
                if not near.any():
                    break
                labels[idx[near]] = labels[owned[nn[near]]]
                todo[idx[near]] = False
                owned = np.nonzero(labels >= 0)[0]
                tree = cKDTree(world[owned])
    idx = np.nonzero(todo)[0]
    if len(idx):
        lab = cluster(world[idx], cell)
        if (lab >= 0).any():
            counts = np.bincount(lab[lab >= 0])
            for c in np.nonzero(counts >= min_points)[0]:
                labels[idx[lab == c]] = len(names)
                names.append(f"cluster{len(names)}")
    return labels, names


#: Face planes of a cluster: Open3D RANSAC planes (inlier distance :data:`PATCH_DIST`
#: times the plane threshold), up to this many, each holding this share of the cluster.
PATCH_MAX_PLANES = 16
PATCH_MIN_SHARE = 0.005
PATCH_DIST = 1.5
#: RANSAC looks for each plane among at most this many of the cluster's points.
PATCH_SAMPLE = 20000
#: Plane hypotheses (point triples) per RANSAC round of the face patches, each scored on
#: the whole sample, as Open3D's ``segment_plane(num_iterations=200)`` that it replaces
#: (scoring 300 on a 6,000-point subsample lowered the rooms' support F1 71.3 -> 66.7;
#: 500 gave 69.4; boxes 85.7-86.7 either way).
PATCH_HYPOTHESES = 200
#: Two patches whose pixels come this close (pixels) are neighbours: a Kinect frame
#: smears a crease over a few pixels that fit neither plane (4 and 7 were tried on the
#: real scans: 7 joined more of the pieces of one object, rooms 66.7 -> 71.3).
PATCH_NEAR_PX = 7
#: Neighbouring patches meeting concavely at more than this angle (degrees) are two
#: objects; so are neighbours whose points, where they meet, lie a depth step off each
#: other's plane.
SPLIT_CREASE_DEG = 25.0
SPLIT_STEP_REL = 0.03
SPLIT_STEP_MIN = 0.04
#: Neighbouring patches whose planes are within 45 degrees of parallel (not two faces of
#: one box, which meet square) and whose median colours differ by more than
#: :data:`SPLIT_COLOUR_DE` (CIE Lab: L 0-100) are two objects.
COLOUR_COS = float(np.cos(np.radians(45.0)))
SPLIT_COLOUR_DE = 30.0
#: A piece must hold this share of its cluster (and ``min_points``) to become an object.
SPLIT_MIN_SHARE = 0.01


def _patches(points: np.ndarray, pix: np.ndarray, shape: tuple[int, int], dist: float,
             min_points: int, seed: int = 0) -> np.ndarray:
    """Per point the index of its planar patch (-1 none): RANSAC planes (on at most
    :data:`PATCH_SAMPLE` points, refitted by least squares to their inliers; every point
    within ``dist`` of a plane is its), each cut into the pieces that are connected in
    the image.

    The RANSAC is :func:`pipeline.planes.ransac_plane`, seeded, rather than Open3D's
    ``segment_plane``: that one draws its samples on all OpenMP threads from one
    generator, so with more than one thread the same frame gave different objects from
    run to run (Shao's 3 boxes: 2 or 3 objects).
    """
    import cv2

    from .planes import fit_plane_lsq, ransac_plane

    out = np.full(len(points), -1, np.int64)
    left = np.arange(len(points))
    rng = np.random.default_rng(seed)
    n_patch = 0
    for _ in range(PATCH_MAX_PLANES):
        if len(left) < max(min_points, 3):
            break
        sample = left if len(left) <= PATCH_SAMPLE else np.sort(
            rng.choice(left, PATCH_SAMPLE, replace=False))
        sub = points[sample]
        nrm, off, cnt = ransac_plane(sub, dist, rng, hypotheses=PATCH_HYPOTHESES,
                                     score_sample=len(sub))
        if cnt * len(left) < min_points * len(sample):
            break
        if cnt >= 3:
            nrm, off = fit_plane_lsq(sub[np.abs(sub @ nrm + off) < dist])
        idx = left[np.abs(points[left] @ nrm + off) < dist]
        mask = np.zeros(shape, np.uint8)
        mask[pix[idx, 0], pix[idx, 1]] = 1
        mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))
        count, comp = cv2.connectedComponents(mask, connectivity=8)
        c_of = comp[pix[idx, 0], pix[idx, 1]]
        sizes = np.bincount(c_of, minlength=count)
        for k in np.flatnonzero(sizes >= min_points):
            if k:
                out[idx[c_of == k]] = n_patch
                n_patch += 1
        left = np.setdiff1d(left, idx, assume_unique=True)
    return out


def _neighbours(patch: np.ndarray, pix: np.ndarray, shape: tuple[int, int]
                ) -> dict[tuple[int, int], tuple[np.ndarray, np.ndarray]]:
    """Pairs of patches (a < b) whose pixels come within :data:`PATCH_NEAR_PX` along rows
    or columns -> (point indices on a's side, point indices on b's side) of those pixel
    pairs."""
    H, W = shape
    pimg = np.full(shape, -1, np.int64)
    pimg[pix[:, 0], pix[:, 1]] = patch
    iimg = np.full(shape, -1, np.int64)
    iimg[pix[:, 0], pix[:, 1]] = np.arange(len(pix))
    P = int(patch.max()) + 1
    keys, ia, ib = [], [], []
    for k in range(1, PATCH_NEAR_PX + 1):
        for dv, du in ((0, k), (k, 0)):
            a, b = pimg[:H - dv, :W - du], pimg[dv:, du:]
            m = (a >= 0) & (b >= 0) & (a != b)
            if not m.any():
                continue
            pa, pb = a[m], b[m]
            xa, xb = iimg[:H - dv, :W - du][m], iimg[dv:, du:][m]
            swap = pa > pb
            keys.append(np.where(swap, pb, pa) * P + np.where(swap, pa, pb))
            ia.append(np.where(swap, xb, xa))
            ib.append(np.where(swap, xa, xb))
    if not keys:
        return {}
    keys, ia, ib = np.concatenate(keys), np.concatenate(ia), np.concatenate(ib)
    order = np.argsort(keys, kind="stable")
    keys, ia, ib = keys[order], ia[order], ib[order]
    uniq, start = np.unique(keys, return_index=True)
    bounds = list(start[1:]) + [len(keys)]
    return {(int(u // P), int(u % P)): (ia[s0:s1], ib[s0:s1])
            for u, s0, s1 in zip(uniq, start, bounds)}


def _adopt(piece: np.ndarray, pts: np.ndarray, pix: np.ndarray, shape: tuple[int, int],
           near: float = 0.05) -> None:
    """Give every point of ``piece == -1`` the piece of its nearest owned point within
    ``near`` metres, else of the nearest owned pixel in the image (in place)."""
    import cv2
    from scipy.spatial import cKDTree

    owned = piece >= 0
    if owned.all():
        return
    lost = np.flatnonzero(~owned)
    d, nn = cKDTree(pts[owned]).query(pts[lost], distance_upper_bound=near)
    hit = np.isfinite(d)
    piece[lost[hit]] = piece[owned][nn[hit]]
    lost = lost[~hit]
    if len(lost):
        free = np.ones(shape, np.uint8)
        owners = np.flatnonzero(piece >= 0)
        free[pix[owners, 0], pix[owners, 1]] = 0
        _, lab = cv2.distanceTransformWithLabels(free, cv2.DIST_L2, 5,
                                                 labelType=cv2.DIST_LABEL_PIXEL)
        # label k is the k-th zero pixel in row-major order
        zeros = np.flatnonzero(free.ravel() == 0)
        owner_img = np.full(shape, -1, np.int64)
        owner_img[pix[owners, 0], pix[owners, 1]] = piece[owners]
        src = zeros[lab[pix[lost, 0], pix[lost, 1]] - 1]
        piece[lost] = owner_img.ravel()[src]


def split_clusters(labels: np.ndarray, names: list[str], world: np.ndarray,
                   eye: np.ndarray, pixels: np.ndarray, shape: tuple[int, int],
                   min_points: int, plane_threshold: float, image: np.ndarray | None = None
                   ) -> tuple[np.ndarray, list[str]]:
    """Split proximity clusters of a depth image into the objects they hold.

    Evidence: the depth image's face planes and the colour image.  Principle: touching
    objects part where one stands on or against another, so that their faces meet in a
    concave crease, or where one stands in front of another (a depth step); the faces of
    one convex box meet only in convex creases, so a box is never cut into its faces.
    Each cluster's points are cut into planar patches (Open3D RANSAC planes, each split
    into its pieces connected in the image, at least :data:`PATCH_MIN_SHARE` of the
    cluster).  Patches whose pixels come within :data:`PATCH_NEAR_PX` are neighbours;
    neighbours are one object unless their normals ``n`` (turned to the camera) and
    centroids ``x`` meet concavely, ``(n1 - n2) . (x1 - x2) < 0`` at more than
    :data:`SPLIT_CREASE_DEG` (the convexity test of Stein et al. 2014, LCCP), or where
    they meet in the picture each side's points lie off the other's plane by a depth
    step (median, :data:`SPLIT_STEP_REL` of the depth, at least :data:`SPLIT_STEP_MIN`),
    or where, with a colour image, their planes are less than 45 degrees apart (not two
    sides of one box, which meet square and differ in shading) and their median colours
    differ by more than :data:`SPLIT_COLOUR_DE` in CIE Lab: a white box leaning on a
    brown one.  Print on a box lies in the plane of its face, inside one patch, and
    never splits it (cutting at every colour edge did, and lowered the real scans'
    support-graph F1).  The connected groups of patches holding at least
    :data:`SPLIT_MIN_SHARE` of the cluster become objects; every other point of the
    cluster joins the nearest.  A cluster with fewer than two such groups is kept whole
    (nothing separates it).
    Instance and scribble labels are never split.

    ``labels`` (n,), ``names`` as :func:`segment_objects` returns them; ``world`` (n, 3);
    ``eye`` the camera centre (world); ``pixels`` (n, 2) (v, u); ``shape`` the image's.
    Returns new (labels, names).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    out = np.full_like(labels, -1)
    new_names: list[str] = []
    cos_crease = np.cos(np.radians(SPLIT_CREASE_DEG))
    lab = None
    if image is not None and image.shape[:2] == tuple(shape):
        import cv2

        lab = cv2.cvtColor(image.astype(np.float32) / 255.0, cv2.COLOR_RGB2Lab)
    for k, name in enumerate(names):
        sel = np.flatnonzero(labels == k)
        least = max(min_points, int(SPLIT_MIN_SHARE * len(sel)))
        if not name.startswith("cluster") or len(sel) < 2 * least:
            out[sel] = len(new_names)
            new_names.append(name)
            continue
        pts, pix = world[sel], pixels[sel]
        patch = _patches(pts, pix, shape, PATCH_DIST * plane_threshold,
                         max(min_points, int(PATCH_MIN_SHARE * len(sel))))
        P = int(patch.max()) + 1
        if P < 2:
            out[sel] = len(new_names)
            new_names.append(name)
            continue
        cen, nrm, tone = np.zeros((P, 3)), np.zeros((P, 3)), np.zeros((P, 3))
        for p in range(P):  # centroid, plane normal (turned to the camera), colour
            mine = patch == p
            q = pts[mine]
            cen[p] = q.mean(0)
            if lab is not None:
                tone[p] = np.median(lab[pix[mine, 0], pix[mine, 1]], axis=0)
            n = np.linalg.svd(q - cen[p], full_matrices=False)[2][2]
            nrm[p] = n if n @ (eye - cen[p]) >= 0 else -n
        rows, cols = [], []
        for (a, b), (ia, ib) in _neighbours(patch, pix, shape).items():
            # a step: the points of each side, where the two meet in the picture, lie
            # off the other's plane (the faces of one box meet on both their planes)
            off = np.minimum(np.abs((pts[ia] - cen[b]) @ nrm[b]),
                             np.abs((pts[ib] - cen[a]) @ nrm[a]))
            gap = float(np.median(off))
            concave = ((nrm[a] - nrm[b]) @ (cen[a] - cen[b]) < 0
                       and nrm[a] @ nrm[b] < cos_crease)
            depth = float(min(np.linalg.norm(cen[a] - eye), np.linalg.norm(cen[b] - eye)))
            step = gap > max(SPLIT_STEP_MIN, SPLIT_STEP_REL * depth)
            # two faces that are not square to each other (not two sides of one box)
            # and differ in colour are two objects' faces (a white box on a brown one)
            colour = (lab is not None and not (concave or step)
                      and float(nrm[a] @ nrm[b]) > COLOUR_COS
                      and float(np.linalg.norm(tone[a] - tone[b])) > SPLIT_COLOUR_DE)
            if not (concave or step or colour):
                rows.append(a)
                cols.append(b)
        g = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(P, P))
        _, group = connected_components(g, directed=False)
        piece = np.where(patch >= 0, group[np.maximum(patch, 0)], -1)
        sizes = np.bincount(piece[piece >= 0], minlength=int(group.max()) + 1)
        big = np.flatnonzero(sizes >= least)
        if len(big) < 2:
            out[sel] = len(new_names)
            new_names.append(name)
            continue
        lut = np.full(len(sizes), -1, np.int64)
        lut[big] = np.arange(len(big))
        piece = np.where(piece >= 0, lut[np.maximum(piece, 0)], -1)
        _adopt(piece, pts, pix, shape)
        for q in range(len(big)):
            out[sel[piece == q]] = len(new_names)
            new_names.append("cluster")
    # clusters are named by position, as segment_objects names them
    return out, [f"cluster{i}" if nm.startswith("cluster") else nm
                 for i, nm in enumerate(new_names)]
