"""Sizes from rib pitches: whether a capture's clear pitches follow its size table's
spacings, and the bars left between two sizes that a pitch tells apart (or a size it
overturns).
"""

from __future__ import annotations

import math
from collections import Counter, defaultdict

import numpy as np

from .barsizes import _nearest, bar_system, rib_pitch_mm
from .decision import _matches_design, _sized
from .params import MEASURED, NOT_MEASURED
from .ribs import _clear_pitch, _edge_pitch, _rib_periodicity, _ribs_in_view


def _pitch_table(clear: dict, keys, prm, *, system, sizes_of=None):
    """Whether a capture's clear rib pitches follow its size system's spacings (see
    :func:`_pitch_settle`): ``(scale, spread, confidence)``, or None where they cannot show it.

    ``clear``: bar index -> (pitch mm, relative resolution); ``keys``: each bar's size (its
    design's); ``sizes_of(i)``: the sizes bar i may be (default its key). The pitches are grouped
    by size; at least ``prm.rib_min_bars`` of them in groups of two or more. In each group, the
    table's spacing nearest to the most of its pitches must be its own size's (ties count: a bar
    of another size than designed, whose pitch is its own size's, does not outvote the design),
    and at least ``prm.rib_min_bars`` pitches in all must be nearest to their own size's.
    ``scale``: 1 + the median deviation of those pitches from their spacings (shared by all: the
    depth scale, the focal length); ``spread``: their robust spread about it; ``confidence``:
    (k + 1) / (n + 2), k of the n pitches within :func:`_pitch_band` of the scaled spacing of a
    size their bar may be."""
    sysm = bar_system(system)
    if not sysm.rib_pitch_mm:
        return None
    table = np.array(sysm.rib_pitch_mm, float)
    groups = defaultdict(list)
    for i in clear:
        if math.isfinite(rib_pitch_mm(keys[i], system=system)):
            groups[keys[i]].append(i)
    groups = {k: v for k, v in groups.items() if len(v) >= 2}
    if sum(len(v) for v in groups.values()) < prm.rib_min_bars:
        return None
    own = []  # (bar, its size's spacing) for the pitches nearest to their own size's spacing
    for k, v in groups.items():
        lk = rib_pitch_mm(k, system=system)
        nearest, leads = _nearest_spacings(table, [clear[i][0] for i in v], lk)
        if not leads:
            return None
        own += [(i, lk) for i, x in zip(v, nearest) if x == lk]
    if len(own) < prm.rib_min_bars:
        return None
    dev = np.array([clear[i][0] / lk - 1 for i, lk in own])
    # a scale all of the capture's pitches share (the camera's depth scale, its focal length) is
    # the capture's, not the bars': pitches are matched to the table times it
    scale = 1 + float(np.median(dev))
    spread = 1.4826 * float(np.median(np.abs(dev - np.median(dev))))
    sizes_of = sizes_of or (lambda i: {keys[i]})
    members = [i for v in groups.values() for i in v]
    agree = sum(
        any(
            abs(clear[i][0] / (scale * rib_pitch_mm(sz, system=system)) - 1) <= _pitch_band(spread, clear[i][1], prm)
            for sz in sizes_of(i)
        )
        for i in members
    )
    return scale, spread, (agree + 1) / (len(members) + 2)


def _nearest_spacings(table, pitches, own: float) -> tuple:
    """``(nearest, leads)``: the table's spacing nearest each pitch, and whether ``own`` (the
    pitches' design size's spacing) is nearest to the most of them (ties count for it; no
    pitches, nothing against it)."""
    nearest = [float(table[np.abs(table - p).argmin()]) for p in pitches]
    counts = Counter(nearest)
    return nearest, counts[own] >= max(counts.values(), default=0)


def _pitch_band(spread, resolution, prm) -> float:
    """How far (relative) a pitch may lie from a scaled spacing and still match it:
    ``prm.pitch_k`` standard errors, each the capture's robust spread of pitches and the read's
    own resolution (half a periodogram bin) together. A robust spread of a dozen pitches that
    cluster on a few values of the periodogram's grid falls short of how far single reads stray
    (seen: 12 reads of one size within ±0.7 %, spread 0.14 %), and the resolution bounds how
    finely one read places its pitch."""
    return prm.pitch_k * math.hypot(spread, resolution)


def _colour_ribs(results, keys, prm, *, system) -> bool:
    """Whether the colour image shows the ribs of a capture whose mask widths do not: a learnt
    mask may smooth the ribs away, so that the capture looks like one without resolved ribs,
    and its bars' median widths (mostly core) read a size down.

    The colour widths (between the colour edges next to the mask's, :func:`_colour_edges_rgb`)
    must pass both tests the mask widths' periodicity passes (:func:`_ribs_in_view`) and also
    follow the size table's spacings (:func:`_pitch_table`, confidence at least
    ``prm.min_confidence``): on smooth bars the colour edges of a slanted bar step with the pixel
    grid, periodically and alike on parallel bars, but not at their sizes' rib spacing. A bar's
    pitch agrees with the table at its design size's spacing or at the next size's up or down:
    a bar of another size than designed is most often its neighbour, and its pitch is its own
    size's (the design's groups must still mostly show their own spacing). Only for systems that
    set a spacing per size (GB 1499.2)."""
    sysm = bar_system(system)
    if not sysm.rib_pitch_mm:
        return False
    reads, lengths = [], []
    for r in results:
        s, cw = r.colour_widths
        good = np.isfinite(cw)
        enough = good.sum() >= prm.rib_min_sections
        reads.append(_rib_periodicity(s[good], cw[good], band=prm.rib_band) if enough else (math.nan, 1.0))
        lengths.append(float(np.ptp(s[good])) if enough else 0.0)
    if _ribs_in_view(reads, prm, keys) >= prm.rib_capture_p:
        return False
    clear = {
        i: c
        for i, ((q, p), length) in enumerate(zip(reads, lengths))
        if (c := _clear_pitch(q, p, length, prm)) is not None
    }
    fit = _pitch_table(clear, keys, prm, system=system, sizes_of=lambda i: sysm.neighbours(keys[i]))
    return fit is not None and fit[2] >= prm.min_confidence


def _mask_ribs_follow_table(results, keys, prm, *, system) -> bool:
    """Whether the rib pitches a capture's mask widths show clearly lie at the size table's
    spacings: True for a system that sets no spacing per size.

    Periodic mask widths alone (:func:`_ribs_in_view`) are not enough: a depth camera that
    fattens its edges widens the fused mask in patches, and on smooth bars those patches gave
    3-5 bars of a capture a common clear "pitch" (Φ14 bars at 11.3-12.9 mm, Φ12 at 10.1-10.7 mm,
    against the table's 9.0 and 8.0 mm); read from its crests, every bar of the capture was then
    a size up, and the widths calibrated on them agreed (docs/decisions/047). Ribs repeat at
    their standard's spacing; a sensor's or a mask's texture does not. A clear pitch agrees where
    the table's spacing nearest to it is its design size's or a neighbour's (a bar of another
    size than designed has its own), and in each design size with two or more clear pitches the
    spacing nearest to the most of them is its own (as in :func:`_pitch_table`: a common period
    of parallel bars near a neighbour's spacing does not pass); the capture's pitches follow the
    table where (agreeing + 1) / (clear + 2) reaches ``prm.min_confidence``. Unlike
    :func:`_pitch_table`, a size with one clear pitch counts: a capture whose ribs show on
    three bars of two sizes, each within 0.3 % of its spacing, passes. Only the pitches that agree
    with their size's median (as :func:`_ribs_in_view` counts them) are read against the table."""
    sysm = bar_system(system)
    if not sysm.rib_pitch_mm:
        return True
    table = np.array(sysm.rib_pitch_mm, float)
    clear = defaultdict(list)  # design size -> its bars' clear pitches
    for i, r in enumerate(results):
        if math.isfinite(keys[i]) and _clear_pitch(r.rib_pitch_mm, r.rib_p, r.rib_length_mm, prm) is not None:
            clear[keys[i]].append(float(r.rib_pitch_mm))
    # the pitches that made the capture ribbed: those within prm.rib_pitch_tol of their size's
    # median clear pitch (:func:`_ribs_in_view`); a stray read of one bar (15.3 mm among Φ12s
    # at 8.02) is no rib spacing of the capture's, and not held against it
    agree = n_clear = 0
    for key, v in clear.items():
        med = float(np.median(v))
        kept = [q for q in v if abs(q / med - 1) <= prm.rib_pitch_tol]
        spacings, leads = _nearest_spacings(table, kept, rib_pitch_mm(key, system=system))
        if len(spacings) >= 2 and not leads:
            return False
        allowed = {rib_pitch_mm(sz, system=system) for sz in sysm.neighbours(key)}
        agree += sum(x in allowed for x in spacings)
        n_clear += len(spacings)
    return (agree + 1) / (n_clear + 2) >= prm.min_confidence


def _pitch_settle(rows, results, keys, shadows, prm, *, system, face=None) -> None:
    """Bars left between two sizes, sized by their rib pitch where the standard sets one per size.

    Where a capture resolves ribs, each bar whose section widths are clearly periodic has a rib
    pitch (:func:`_rib_periodicity`), and GB 1499.2 sets the spacing l of each size (Φ12 8.0 mm,
    Φ14 9.0 mm: :func:`rib_pitch_mm`). A bar "not measured" because its widths lie between two
    sizes (ambiguous, crests against core, mask against point cloud: ``row["_pair"]``) is sized
    where its pitch lies within the band of exactly one of the two and they differ in l (and of
    no size between them: a pair of sizes two apart, Φ14 and Φ18, is not told apart by a pitch
    that Φ16 shares). Its pitch is its width's where that is clear, else the one both its edges
    show (:func:`_edge_pitch`), else the one the shading of its face shows (``face(i)``,
    :func:`_face_pitch`, on its visible half where it is seen from one side: read only where
    needed, once a bar).

    First the capture must show that its bars follow the table: the bars with a clear pitch (in
    their widths; where those are too few to show it, in their faces too) are grouped by
    ``keys`` (each bar's design size, else the size its width is nearest to); at least
    ``prm.rib_min_bars`` of them in groups of two or more, and in every such group most
    pitches nearest to its own size's l among the table's pitches (:func:`_pitch_table`: bars
    rolled by another standard, or a renderer's own rib spacing, fail here and the pitch is not
    used). Pitches are matched to the table times the scale they share (1 + their median
    deviation from it: the camera's depth scale or focal length a little off moves them all).
    The band (:func:`_pitch_band`) is ``prm.pitch_k`` standard errors, each the robust spread of
    those pitches about that scale (what this capture's bars and mill show) and the bar's own
    pitch resolution (half a periodogram bin, pitch / (2 x the length read)) together. The
    size's confidence is the share of the capture's clear pitches inside the band of a size the
    bar may be (its design size, the size its widths gave, or one of the two they left it
    between), (k + 1) / (n + 2): a capture with few pitches to check the table against gives a
    confidence to match, and one whose pitches often match nothing the bar may be, a low one.
    Rows are changed in place."""
    sysm = bar_system(system)
    if not sysm.rib_pitch_mm:
        return
    clear = {
        i: c
        for i, r in enumerate(results)  # bar index -> (pitch, relative resolution)
        if (c := _clear_pitch(r.rib_pitch_mm, r.rib_p, r.rib_length_mm, prm)) is not None
    }

    def sizes_of(i):  # what bar i may be: its design size, what its widths gave or left it between
        row = rows[i]
        return {keys[i]} | ({row["nominal_mm"]} if row["diameter_status"] == MEASURED else set(row.get("_pair", ())))

    faces = {}  # bar index -> its face's read (None: none clear), each read once

    def face_read(i):
        if i not in faces:
            faces[i] = face(i) if face is not None else None
        return faces[i]

    fit = _pitch_table(clear, keys, prm, system=system, sizes_of=sizes_of)
    if (fit is None or fit[2] < prm.min_confidence) and face is not None:
        # too few widths clearly periodic to test the table: the faces of the others may show it
        more = {i: c for i in range(len(rows)) if i not in clear and (c := face_read(i)) is not None}
        fit = _pitch_table({**clear, **more}, keys, prm, system=system, sizes_of=sizes_of)
    if fit is None or fit[2] < prm.min_confidence:
        return
    scale, spread, conf = fit
    reads = {}  # bar index -> (its pitch read, where), for the bars left between two sizes
    for i, row in enumerate(rows):
        pair = row.get("_pair")
        if row["diameter_status"] != NOT_MEASURED or pair is None:
            continue
        # a bar whose width shows no clear pitch may show it along each of its edges, or in the
        # shading of its face
        read, where = (clear[i], "") if i in clear else (_edge_pitch(results[i], prm), " (along both edges)")
        if read is None:
            read, where = face_read(i), " (in the shading along its face)"
        if read is not None:
            reads[i] = (read, where)
    # the pitches read along edges and faces size bars only where they too follow the table with
    # the capture's: a renderer's or a mill's own spacing on a whole design group (a Φ12 group's
    # faces all at 9.7 mm, nearest Φ16's 10 mm) is no GB 1499.2 rib pitch, and read against the
    # table it names a wrong size (decision 047)
    extra = {i: read for i, (read, _) in reads.items() if i not in clear}
    if extra:
        every = {**clear, **{i: c for i, c in faces.items() if c is not None and i not in clear}, **extra}
        again = _pitch_table(every, keys, prm, system=system, sizes_of=sizes_of)
        if again is None or again[2] < prm.min_confidence:
            reads = {i: r for i, r in reads.items() if i in clear}
    for i, (read, where) in reads.items():
        _size_by_pitch(rows[i], read, where, results[i], shadows[i], scale, spread, conf, prm, system=system)


def _size_by_pitch(row, read, where, reading, in_shadow, scale, spread, conf, prm, *, system) -> None:
    """Size a bar left between two sizes (``row["_pair"]``) by its rib pitch ``read``
    (``(pitch, relative resolution)``, read ``where``) where it lies within the band of exactly
    one of the sizes from one of the two to the other (the capture's ``scale`` and ``spread``
    of pitches, :func:`_pitch_table`), and that size is one of the two; the row is changed in
    place."""
    sysm = bar_system(system)
    pair = row["_pair"]
    p, resolution = read
    ls = [rib_pitch_mm(sz, system=system) for sz in pair]
    if not all(math.isfinite(x) for x in ls):
        return
    # The pitch must name one size among all those from one of the two to the other, not
    # only between the two (two sizes of one spacing then both match, and the pitch names
    # neither): a mask and a point cloud that disagree may leave a bar between Φ14 and Φ18,
    # and a pitch of 10 mm is Φ16's as much as Φ18's.
    band = _pitch_band(spread, resolution, prm)
    span = [sz for sz in sysm.sizes_mm if min(pair) - 1e-6 <= sz <= max(pair) + 1e-6]
    on = [sz for sz in span if abs(p / (scale * rib_pitch_mm(sz, system=system)) - 1) <= band]
    if len(on) != 1 or on[0] not in pair:
        return
    j = list(pair).index(on[0])
    size, other = pair[j], pair[1 - j]
    why = row["diameter_reason"].removesuffix(": check it by hand")
    reason = (
        f"size from the rib pitch {p:.2f} mm{where}: {sysm.label(size)}'s is {ls[j]:g} mm, "
        f"{sysm.label(other)}'s {ls[1 - j]:g} mm (the widths alone: {why})"
    )
    width = row["width_used_mm"] if math.isfinite(row["width_used_mm"]) else reading.mask_width_mm
    _sized(
        row,
        size,
        conf,
        width,
        row["width_sigma_mm"],
        (row["width_source"] or "mask") + "+pitch",
        reason,
        in_shadow,
        prm,
    )
    row["matches_design"] = _matches_design(size, row["design_diameter_mm"])


def _pitch_veto(rows, results, prm, *, system) -> None:
    """A bar sized from its widths whose own widths are clearly periodic at the rib spacing of the
    next size up (GB 1499.2 sets one per size) is not reported at the smaller size: it is "not
    measured", a possible wrong size whose reason names both.

    A mask that smooths a ribbed bar's ribs away reads its core, about the envelope of the size
    below (Φ16's core is Φ14's envelope); where the capture as a whole shows no ribs, neither
    :func:`_pitch_settle` nor the colour image's ribs (:func:`_colour_ribs`) can mend that, but
    the bar's own widths may still show its ribs' pitch. The pitch must lie within
    :func:`_pitch_band` of the next size's spacing on the read's resolution alone (no capture
    spread to add: the table was not checked against this capture) and outside its own size's.
    It overturns a size, so it asks more of the periodicity than a reported pitch does (p <
    ``prm.rib_bar_p``, 1 %): what a whole capture needs to be judged to show ribs, p <
    ``prm.rib_capture_p``. Among some 600 smooth bars a few are periodic at p ~ 10⁻³ by chance,
    one of them right at the next size's spacing (``docs/diameters.md``); the Φ16 bar read as
    Φ14 that this was written for, at 2 × 10⁻¹³. Only the size up: no mechanism reads a ribbed
    bar a size up, and chance pitches fall on either side. Rows are changed in place."""
    sysm = bar_system(system)
    if not sysm.rib_pitch_mm:
        return
    sizes = list(sysm.sizes_mm)
    for row, r in zip(rows, results):
        if (
            row["diameter_status"] != MEASURED
            or "pitch" in (row["width_source"] or "")
            or not r.rib_p < prm.rib_capture_p
        ):  # (stricter than _clear_pitch's p)
            continue
        read = _clear_pitch(r.rib_pitch_mm, r.rib_p, r.rib_length_mm, prm)
        j = _nearest(sizes, row["nominal_mm"])
        if read is None or j + 1 >= len(sizes):
            continue
        p, resolution = read
        own, up = rib_pitch_mm(sizes[j], system=system), rib_pitch_mm(sizes[j + 1], system=system)
        if not (math.isfinite(own) and math.isfinite(up)):
            continue
        band = _pitch_band(0.0, resolution, prm)
        if abs(p / up - 1) > band or abs(p / own - 1) <= band:
            continue
        this, next_up = sysm.label(sizes[j]), sysm.label(sizes[j + 1])
        conf = row["confidence"]
        reason = (
            f"possible wrong size: the widths give {this} (confidence {conf:.2f}), but "
            f"they are periodic with a pitch of {p:.2f} mm, the rib spacing of {next_up} "
            f"({up:g} mm; {this}'s is {own:g} mm): a mask that smooths the ribs away "
            "reads a bar's core, a size down; check this bar by hand"
        )
        row.update(
            diameter_status=NOT_MEASURED,
            matches_design=None,
            nominal_mm=math.nan,
            confidence=0.0,
            diameter_reason=reason,
        )
