"""Figures drawn with OpenCV: overlays and side-by-side views of store items."""
from __future__ import annotations

import cv2
import numpy as np

from .io.images import read_image
from .labels import IGNORE, ROAD, decode_label, get_label_format
from .store.layout import Store

__all__ = ["to_bgr8", "overlay_label", "bev_figure", "warp_figure", "vp_figure", "completion_figure", "footprints_figure", "fov_figure",
           "prior_figure"]


def to_bgr8(img: np.ndarray) -> np.ndarray:
    """Any stored image (grey/colour, 8/16-bit) -> 3-channel uint8 for drawing."""
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    return np.ascontiguousarray(img)


def overlay_label(img: np.ndarray, label: np.ndarray | None, alpha: float = 0.45) -> np.ndarray:
    """Road in green, ignore darkened."""
    out = to_bgr8(img).copy()
    if label is None:
        return out
    road = label == ROAD
    out[road] = ((1 - alpha) * out[road] + alpha * np.array([0, 255, 0])).astype(np.uint8)
    ign = label == IGNORE
    out[ign] = (out[ign] * 0.4).astype(np.uint8)
    return out


def _fit(img: np.ndarray, w: int, h: int) -> np.ndarray:
    s = min(w / img.shape[1], h / img.shape[0])
    r = cv2.resize(img, (max(1, int(img.shape[1] * s)), max(1, int(img.shape[0] * s))), interpolation=cv2.INTER_AREA)
    canvas = np.full((h, w, 3), 32, np.uint8)
    y0, x0 = (h - r.shape[0]) // 2, (w - r.shape[1]) // 2
    canvas[y0:y0 + r.shape[0], x0:x0 + r.shape[1]] = r
    return canvas


VP_RED, COVERED_YELLOW = (0, 0, 255), (0, 255, 255)  # BGR
# what the marks of warp_figure mean: (symbol, text), drawn in one line under the rows
WARP_LEGEND = (("road", "road"), ("ignore", "ignore"), ("outline", "real pixels (outside: completed)"),
               ("vp", "road vanishing point (every image's is mapped here)"))


def warp_figure(store: Store, ids: list[str] | None = None, width: int = 1400, max_items: int = 6) -> np.ndarray:
    """Rows of (original with label | virtual with label, covered region outlined in yellow, the
    road vanishing point as a red +), and a legend line (:data:`WARP_LEGEND`) under them."""
    recs = [store.get(i) for i in ids] if ids else list(store)[:max_items]
    vw, vh = store.store_size
    col = width // 2
    row_h = int(col * vh / vw) + 28
    rows = []
    for rec in recs:
        src = read_image(rec["source"]).array
        lab = None
        if rec.get("label_source") and rec.get("label_format"):
            raw = read_image(rec["label_source"], label=True).array
            lab = decode_label(raw, get_label_format(rec["label_format"]), rec["label_source"])
        left = overlay_label(src, lab)
        vimg = read_image(store.path(rec["image"])).array
        vlab = read_image(store.path(rec["label"]), label=True).array if rec.get("label") else None
        right = overlay_label(vimg, vlab)
        valid = read_image(store.path(rec["valid"]), label=True).array
        contours, _ = cv2.findContours(valid.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        cv2.drawContours(right, contours, -1, COVERED_YELLOW, max(1, vw // 400))
        u, v = store.virtual.cx, store.virtual.cy  # H maps each item's road VP to the principal point
        cv2.drawMarker(right, (int(round(u)), int(round(v))), VP_RED, cv2.MARKER_CROSS, max(8, vw // 40), 2)
        pair = np.hstack([_fit(left, col, row_h - 28), _fit(right, col, row_h - 28)])
        bar = np.full((28, width if pair.shape[1] == width else pair.shape[1], 3), 255, np.uint8)
        cv2.putText(bar, f"{rec['id']}  ({rec['camera']}, {rec['size'][0]}x{rec['size'][1]})", (8, 20),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
        cv2.putText(bar, f"virtual camera {vw}x{vh}", (col + 8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1,
                    cv2.LINE_AA)
        rows.append(np.vstack([bar, pair]))
    rows.append(_warp_legend(rows[0].shape[1] if rows else width))
    return np.vstack(rows)


def _warp_legend(width: int, h: int = 28) -> np.ndarray:
    """One white line: a symbol and its meaning per :data:`WARP_LEGEND` entry, the font shrunk
    to fit ``width``."""
    font, gap, sym = cv2.FONT_HERSHEY_SIMPLEX, 18, 16
    texts = [t for _, t in WARP_LEGEND]
    natural = sum(cv2.getTextSize(t, font, 0.55, 1)[0][0] for t in texts) + len(texts) * (sym + 6 + gap) + 8
    fs = 0.55 * min(1.0, (width - 8) / natural)
    bar = np.full((h, width, 3), 255, np.uint8)
    x, y = 8, h // 2
    for kind, text in WARP_LEGEND:
        if kind in ("road", "ignore"):
            swatch = overlay_label(np.full((sym, sym, 3), 200, np.uint8),
                                   np.full((sym, sym), ROAD if kind == "road" else IGNORE, np.uint8))
            bar[y - sym // 2:y - sym // 2 + sym, x:x + sym] = swatch
        elif kind == "outline":
            cv2.rectangle(bar, (x, y - sym // 2), (x + sym - 1, y + sym // 2 - 1), COVERED_YELLOW, 2)
        else:
            cv2.drawMarker(bar, (x + sym // 2, y), VP_RED, cv2.MARKER_CROSS, sym, 2)
        x += sym + 6
        cv2.putText(bar, text, (x, y + 5), font, fs, (0, 0, 0), 1, cv2.LINE_AA)
        x += cv2.getTextSize(text, font, fs, 1)[0][0] + gap
    return bar


def vp_figure(image: np.ndarray, result, cam=None, prior_box=None) -> np.ndarray:
    """The road-VP evidence of one image (``result``: a :class:`vcprep.vp.VPResult`):
    all line segments thin grey, supporting segments green and extended to the VP (thin), the
    prior window (VPs allowed by the reliability rule) as a cyan box, the detector's VP as a red
    cross, the final VP as a yellow circle (differs after a fallback), and a status caption."""
    out = to_bgr8(image).copy()
    h, w = out.shape[:2]
    lw = max(1, w // 480)
    seg, sup = result.segments, result.support
    for i, s in enumerate(seg):
        if len(sup) and sup[i]:
            continue
        cv2.line(out, (int(round(s[0])), int(round(s[1]))), (int(round(s[2])), int(round(s[3]))), (160, 160, 160), lw,
                 cv2.LINE_AA)
    # the canvas is enlarged when the VP or the prior box lies outside the image
    det = result.detected
    for i in np.flatnonzero(sup) if len(sup) else []:
        s = seg[i]
        if det is not None:
            m = ((s[0] + s[2]) / 2, (s[1] + s[3]) / 2)
            cv2.line(out, (int(round(m[0])), int(round(m[1]))), (int(round(det[0])), int(round(det[1]))),
                     (0, 160, 0), 1, cv2.LINE_AA)
        cv2.line(out, (int(round(s[0])), int(round(s[1]))), (int(round(s[2])), int(round(s[3]))), (0, 255, 0),
                 2 * lw, cv2.LINE_AA)
    if prior_box is not None:
        u0, v0, u1, v1 = prior_box
        cv2.rectangle(out, (int(round(u0)), int(round(v0))), (int(round(u1)), int(round(v1))), (255, 255, 0), lw)
    mk = max(12, w // 30)
    if det is not None:
        cv2.drawMarker(out, (int(round(det[0])), int(round(det[1]))), (0, 0, 255), cv2.MARKER_CROSS, mk, 2 * lw)
    vp = result.vp
    cv2.circle(out, (int(round(vp[0])), int(round(vp[1]))), mk // 2, (0, 255, 255), 2 * lw, cv2.LINE_AA)
    caption = (f"{result.status}  vp=({vp[0]:.1f}, {vp[1]:.1f})  pan {result.pan_deg:+.1f}  tilt {result.tilt_deg:+.1f}"
               f"  support {result.n_support}  conf {result.confidence:.2f}")
    bar = np.full((28 + (22 if result.reason else 0), w, 3), 255, np.uint8)
    fs = min(0.55, w / 1100)
    cv2.putText(bar, caption, (6, 19), cv2.FONT_HERSHEY_SIMPLEX, fs, (0, 0, 0), 1, cv2.LINE_AA)
    if result.reason:
        cv2.putText(bar, result.reason[:160], (6, 41), cv2.FONT_HERSHEY_SIMPLEX, fs * 0.9, (0, 0, 160), 1, cv2.LINE_AA)
    return np.vstack([out, bar])


def _dashed_contours(img: np.ndarray, mask: np.ndarray, colour, thickness: int, dash: int) -> None:
    """Outline ``mask`` with a dashed polyline (dash and gap ``dash`` pixels long)."""
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    for c in contours:
        pts = c[:, 0, :]
        for i in range(0, len(pts) - 1, 2 * dash):
            seg = pts[i:i + dash + 1]
            if len(seg) > 1:
                cv2.polylines(img, [seg.reshape(-1, 1, 2)], False, colour, thickness, cv2.LINE_AA)


def completion_figure(store: Store, item_id: str, rays: int = 24, width: int = 1400) -> np.ndarray:
    """Paper Fig. 5 for one store item: completed image with the ray centre (VP, red dot), the
    source boundary (covered region outline, red dashed) and a fan of completion rays (green,
    from where each ray leaves the covered region to the image edge) | completed label overlay."""
    rec = store.get(item_id)
    vimg = read_image(store.path(rec["image"])).array
    vlab = read_image(store.path(rec["label"]), label=True).array if rec.get("label") else None
    valid = read_image(store.path(rec["valid"]), label=True).array > 0
    vh, vw = valid.shape
    centre = rec.get("completion_centre")
    if centre is None:  # not projective: show the VP in store coordinates anyway
        H = np.asarray(rec["H"], dtype=np.float64).reshape(3, 3)
        p = H @ np.array([rec["vp"][0], rec["vp"][1], 1.0])
        centre = [p[0] / p[2], p[1] / p[2]]
    cu, cv_ = float(centre[0]), float(centre[1])
    left = to_bgr8(vimg).copy()
    lw = max(1, vw // 500)
    diag = int(np.hypot(vw, vh)) + 2
    t = np.arange(diag, dtype=np.float64)
    for k in range(max(0, rays)):
        a = 2 * np.pi * (k + 0.5) / rays
        xs, ys = cu + t * np.cos(a), cv_ + t * np.sin(a)
        inside = (xs >= 0) & (xs <= vw - 1) & (ys >= 0) & (ys <= vh - 1)
        if not inside.any():
            continue
        xi = np.clip(np.rint(xs), 0, vw - 1).astype(int)
        yi = np.clip(np.rint(ys), 0, vh - 1).astype(int)
        cov = inside & valid[yi, xi]
        if not cov.any():
            continue
        last_in = np.flatnonzero(inside)[-1]
        first_out = np.flatnonzero(cov[: last_in + 1] == 0)
        first_out = first_out[first_out > np.flatnonzero(cov)[0]]
        if not len(first_out):
            continue
        i0 = first_out[0]
        cv2.line(left, (int(round(xs[i0])), int(round(ys[i0]))), (int(round(xs[last_in])), int(round(ys[last_in]))),
                 (0, 200, 0), lw, cv2.LINE_AA)
    _dashed_contours(left, valid, (0, 0, 255), lw, max(4, vw // 120))
    cv2.circle(left, (int(round(cu)), int(round(cv_))), max(3, vw // 150), (0, 0, 255), -1, cv2.LINE_AA)
    right = overlay_label(vimg, vlab)
    col = width // 2
    h = int(col * vh / vw)
    pair = np.hstack([_fit(left, col, h), _fit(right, col, h)])
    bar = np.full((28, pair.shape[1], 3), 255, np.uint8)
    inside_txt = "" if rec.get("completion_vp_inside") in (True, None) else "  (VP outside: fallback centre)"
    cv2.putText(bar, f"{rec['id']}  completion: {rec.get('completion', 'none')}{inside_txt}", (8, 20),
                cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(bar, "completed label (road green, ignore dark)", (col + 8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.55,
                (0, 0, 0), 1, cv2.LINE_AA)
    return np.vstack([bar, pair])


_PALETTE = [(0, 90, 230), (0, 170, 0), (230, 80, 0), (160, 0, 160), (0, 170, 200), (120, 120, 0), (60, 60, 60)]


def _legend(img: np.ndarray, names: list[str], x: int = 12, y: int = 24) -> None:
    for i, name in enumerate(names):
        c = _PALETTE[i % len(_PALETTE)]
        cv2.rectangle(img, (x, y + 22 * i - 12), (x + 16, y + 22 * i + 2), c, -1)
        cv2.putText(img, name, (x + 24, y + 22 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)


def footprints_figure(cameras: list, fraction: float = 0.25, size: int = 800, max_z: float | None = None) -> np.ndarray:
    """Paper Fig. 3: the road-plane footprint (top view, X across, Z ahead, metres) of the lower
    ``fraction`` of each camera's image at its average pose."""
    from .warp.homography import apply_homography, ground_to_image

    polys = []
    for cam in cameras:
        w, h = cam.size
        top = (h - 0.5) - fraction * h
        edge = np.linspace(0, 1, 40)
        pts = np.concatenate([
            np.column_stack([-0.5 + edge * w, np.full(40, top)]),
            np.column_stack([np.full(40, w - 0.5), top + edge * fraction * h]),
            np.column_stack([w - 0.5 - edge * w, np.full(40, h - 0.5)]),
            np.column_stack([np.full(40, -0.5), h - 0.5 - edge * fraction * h]),
        ])
        ground = apply_homography(np.linalg.inv(ground_to_image(cam)), pts)  # (X, Z)
        polys.append(ground)
    allpts = np.concatenate(polys)
    zmax = max_z or float(np.ceil(max(5.0, allpts[:, 1].max() * 1.1)))
    xmax = float(np.ceil(max(2.0, np.abs(allpts[:, 0]).max() * 1.1)))
    scale = (size - 80) / max(zmax, 2 * xmax)
    img = np.full((size, size, 3), 255, np.uint8)
    ox, oy = size // 2, size - 40

    def px(p):
        return np.round(np.column_stack([ox + p[:, 0] * scale, oy - p[:, 1] * scale])).astype(np.int32)

    for z in range(0, int(zmax) + 1, 5):  # grid every 5 m
        y = int(oy - z * scale)
        cv2.line(img, (0, y), (size, y), (225, 225, 225), 1)
        cv2.putText(img, f"{z} m", (size - 60, y - 3), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (120, 120, 120), 1, cv2.LINE_AA)
    cv2.drawMarker(img, (ox, oy), (0, 0, 0), cv2.MARKER_TRIANGLE_UP, 14, 2)
    for i, poly in enumerate(polys):
        cv2.polylines(img, [px(poly)], True, _PALETTE[i % len(_PALETTE)], 2, cv2.LINE_AA)
    _legend(img, [f"{c.name} (h {c.height:g} m)" for c in cameras])
    cv2.putText(img, f"ground footprint of the lower {fraction:g} of each image (top view)", (12, size - 12),
                cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    return img


def fov_figure(cameras: list, virtual, width: int = 1100) -> np.ndarray:
    """Paper Fig. 4: each camera's image outline (average pose) drawn in the virtual image plane."""
    from .warp.homography import apply_homography, check_not_folded, virt_H_src

    s = width / virtual.size[0]
    H_img = int(round(virtual.size[1] * s))
    img = np.full((H_img + 40, width, 3), 255, np.uint8)
    cv2.rectangle(img, (0, 0), (width - 1, H_img - 1), (0, 0, 0), 2)
    cx, cy = virtual.cx * s, virtual.cy * s
    cv2.line(img, (0, int(cy)), (width, int(cy)), (200, 200, 200), 1)
    cv2.drawMarker(img, (int(cx), int(cy)), (0, 0, 255), cv2.MARKER_CROSS, 16, 2)
    for i, cam in enumerate(cameras):
        H = virt_H_src(cam, virtual)
        check_not_folded(H, cam.size, cam.name)
        w, h = cam.size
        edge = np.linspace(0, 1, 40)
        pts = np.concatenate([np.column_stack([-0.5 + edge * w, np.full(40, -0.5)]),
                              np.column_stack([np.full(40, w - 0.5), -0.5 + edge * h]),
                              np.column_stack([w - 0.5 - edge * w, np.full(40, h - 0.5)]),
                              np.column_stack([np.full(40, -0.5), h - 0.5 - edge * h])])
        q = np.round(apply_homography(H, pts) * s).astype(np.int32)
        cv2.polylines(img, [q], True, _PALETTE[i % len(_PALETTE)], 2, cv2.LINE_AA)
    _legend(img, [c.name for c in cameras])
    hf, vf = virtual.fov_deg()
    cv2.putText(img, f"virtual camera '{virtual.name}' {virtual.size[0]}x{virtual.size[1]}, FOV {hf:.1f} x {vf:.1f} deg",
                (12, H_img + 28), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    return img


def prior_figure(prior: np.ndarray, mean: np.ndarray, unknown: np.ndarray | None = None,
                 levels: tuple[float, float] = (0.25, 0.75), caption: str = "", width: int = 1100) -> np.ndarray:
    """The geometric road prior (:mod:`vcprep.prior`) as a heat map (turbo colour map, 0 blue ->
    1 red) over the stores' mean image, with the ``levels`` contours (the surrogate-label
    thresholds: lower dark, upper white); pixels no item labels (``unknown``) show the mean image
    only. A colour bar and ``caption`` below."""
    h0, w0 = prior.shape
    s = width / w0
    size = (width, max(1, int(round(h0 * s))))
    p = cv2.resize(np.asarray(prior, np.float32), size, interpolation=cv2.INTER_LINEAR)
    base = cv2.resize(to_bgr8(mean), size, interpolation=cv2.INTER_LINEAR)
    heat = cv2.applyColorMap(np.clip(np.rint(p * 255), 0, 255).astype(np.uint8), cv2.COLORMAP_TURBO)
    out = cv2.addWeighted(heat, 0.6, base, 0.4, 0.0)
    if unknown is not None:
        unk = cv2.resize(unknown.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0
        out[unk] = base[unk]
    lw = max(1, width // 400)
    for level, colour in zip(levels, ((40, 40, 40), (255, 255, 255))):
        contours, _ = cv2.findContours((p > level).astype(np.uint8), cv2.RETR_LIST, cv2.CHAIN_APPROX_SIMPLE)
        cv2.drawContours(out, contours, -1, colour, lw, cv2.LINE_AA)
    bar = np.full((48, size[0], 3), 255, np.uint8)
    x0, x1 = 12, min(size[0] - 12, 312)
    ramp = np.linspace(0, 255, x1 - x0).astype(np.uint8)[None, :].repeat(12, axis=0)
    bar[6:18, x0:x1] = cv2.applyColorMap(ramp, cv2.COLORMAP_TURBO)
    for t in (0.0, *levels, 1.0):
        x = int(round(x0 + t * (x1 - x0 - 1)))
        cv2.line(bar, (x, 18), (x, 22), (0, 0, 0), 1)
        cv2.putText(bar, f"{t:g}", (max(0, x - 8), 36), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    text = f"road prior p_g; contours {levels[0]:g} (dark), {levels[1]:g} (white)" + (f"; {caption}" if caption else "")
    cv2.putText(bar, text, (x1 + 16, 28), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return np.vstack([out, bar])


CAMERA_LEGEND = "cyan line: horizon | cyan +: the camera's average road VP | red +: this frame's road VP | " \
                "red band: own vehicle (ego_rows) | white dot: principal point"


def camera_figure(images: list, camera, vps: dict | None = None, width: int = 1400, columns: int = 2) -> np.ndarray:
    """A camera drawn on sample frames, to see in one look whether it is right: the horizon
    (the row of the camera's average road VP; roll 0), that VP, each frame's own road VP from
    ``vps`` (id -> (u, v), source pixels), the own-vehicle rows shaded, the principal point, and
    a caption with the pose and focal length. ``images``: paths (ids = file stems)."""
    from .warp.homography import vp_from_pose

    tiles = []
    cw = width // columns
    for p in images:
        img = to_bgr8(read_image(p).array)
        h, w = img.shape[:2]
        cam = camera.for_image_size((w, h), p)
        s = cw / w
        t = cv2.resize(img, (cw, max(1, int(round(h * s)))), interpolation=cv2.INTER_AREA)
        if cam.ego_rows:
            y0 = int(round((h - cam.ego_rows) * s))
            band = t[y0:].copy()
            band[..., 2] = np.maximum(band[..., 2], 200)
            t[y0:] = cv2.addWeighted(t[y0:], 0.5, band, 0.5, 0)
            cv2.line(t, (0, y0), (cw - 1, y0), VP_RED, 1, cv2.LINE_AA)
        u, v = vp_from_pose(cam)
        pt = lambda x, y: (int(round((x + 0.5) * s - 0.5)), int(round((y + 0.5) * s - 0.5)))
        cv2.line(t, (0, pt(u, v)[1]), (cw - 1, pt(u, v)[1]), (255, 255, 0), 1, cv2.LINE_AA)
        cv2.drawMarker(t, pt(u, v), (255, 255, 0), cv2.MARKER_CROSS, 22, 2, cv2.LINE_AA)
        own = (vps or {}).get(p.stem) if hasattr(p, "stem") else None
        if own is not None:
            cv2.drawMarker(t, pt(*own), VP_RED, cv2.MARKER_CROSS, 16, 2, cv2.LINE_AA)
        cv2.circle(t, pt(cam.cx, cam.cy), 3, (255, 255, 255), -1, cv2.LINE_AA)
        tiles.append(t)
    th = max(t.shape[0] for t in tiles)
    rows = []
    for i in range(0, len(tiles), columns):
        row = [np.pad(t, ((0, th - t.shape[0]), (0, 0), (0, 0))) for t in tiles[i:i + columns]]
        row += [np.zeros((th, cw, 3), np.uint8)] * (columns - len(row))
        rows.append(np.hstack(row))
    cam0 = camera.for_image_size(read_image(images[0]).size, images[0])
    hf, vf = cam0.fov_deg()
    head = np.full((56, columns * cw, 3), 255, np.uint8)
    cv2.putText(head, f"{camera.name}: tilt {camera.tilt:.2f} deg, pan {camera.pan:.2f} deg, fx {cam0.fx:.0f} fy "
                      f"{cam0.fy:.0f} px ({hf:.0f} x {vf:.0f} deg), height {camera.height:g} m, ego_rows {cam0.ego_rows}",
                (10, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(head, CAMERA_LEGEND, (10, 46), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (60, 60, 60), 1, cv2.LINE_AA)
    return np.vstack([head] + rows)


def vp_figure_of_file(image, camera) -> np.ndarray:
    """:func:`vp_figure` of one image file alone (``vcprep figure vp``): its road VP detected
    and judged by the reliability rule with the default :class:`~vcprep.vp.VPConfig`;
    with no dataset to fall back to, a rejected VP falls back to the camera's average-pose VP.
    ``camera``: the camera of the image at any size (scaled to the image's)."""
    from .vp.estimate import VPConfig, estimate_vp
    from .vp.reliability import apply_reliability
    from .vp.segments import prior_window

    img = read_image(image).array
    cam = camera.for_image_size((img.shape[1], img.shape[0]), image)
    cfg = VPConfig()
    res = apply_reliability([estimate_vp(img, cam, cfg)], [cam])[0]
    return vp_figure(img, res, cam, prior_window(cam, cfg.pan_range, cfg.tilt_range))


def evenly_spread(files: list, n: int) -> list:
    """``n`` of ``files`` (at most all), evenly spread from the first to the last (sample frames)."""
    n = min(n, len(files))
    return [files[round(i * (len(files) - 1) / max(1, n - 1))] for i in range(n)]


def bev_figure(frame: np.ndarray, label: np.ndarray | None, bev_image: np.ndarray, bev_label: np.ndarray,
               grid, road: dict, height: int = 400, corridor: float = 1.8, origin_z: float = 0.0) -> np.ndarray:
    """Frame (road in green) | its bird's-eye view (far row up; road in green, unseen dark), with
    the corridor up to ``road['free_m']`` in yellow, the free distance as a red line and the
    widths of ``road['width_m']`` as white ticks (and the span ``road['edges_m']`` measured, a white line). ``grid`` a :class:`vcprep.bev.BevGrid`;
    ``origin_z`` the camera's foot in the grid's z (:attr:`vcprep.bev.GroundView.origin_z`)."""
    s = height / bev_image.shape[0]
    bev = cv2.resize(overlay_label(bev_image, bev_label), None, fx=s, fy=s, interpolation=cv2.INTER_AREA)

    def px(x: float, z: float) -> tuple[int, int]:  # a road point -> the figure's BEV pixel
        return int(round((x - grid.x_min) / grid.res * s)), int(round((grid.z_max - z) / grid.res * s))

    oz = origin_z
    if road.get("free_m") is not None:
        z = road["free_m"] + oz
        for x in (-corridor / 2, corridor / 2):
            cv2.line(bev, px(x, grid.z_min), px(x, z), (0, 230, 255), 1, cv2.LINE_AA)
        cv2.line(bev, px(-corridor, z), px(corridor, z), (0, 0, 255), 2, cv2.LINE_AA)
        cv2.putText(bev, f"free {road['free_m']:.1f} m", (4, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 255), 1,
                    cv2.LINE_AA)
    for d, w in road.get("width_m", {}).items():
        y = px(0, float(d) + oz)[1]
        cv2.line(bev, (0, y), (6, y), (255, 255, 255), 1)
        edges = (road.get("edges_m") or {}).get(d)
        if edges:  # the span width_m measured
            cv2.line(bev, (px(edges[0], 0)[0], y), (px(edges[1], 0)[0], y), (255, 255, 255), 1, cv2.LINE_AA)
        cv2.putText(bev, f"{d} m: {'-' if w is None else f'{w:.1f} m'}", (8, y + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.38,
                    (255, 255, 255), 1, cv2.LINE_AA)
    left = _fit(overlay_label(frame, label), int(round(frame.shape[1] * height / frame.shape[0] * 0.5)), height)
    return np.hstack([left, np.full((height, 6, 3), 255, np.uint8), bev])
