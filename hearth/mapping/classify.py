"""The types of a draft's large objects (issue 47, stage 4 of the semantic draft): features
of each object box on the fused map, a classifier trained on generated homes (as Rusu et al.,
seed 001, trained theirs on simulated kitchens), and its training.

- ``object_features`` / ``FEATURES``: the box (height, lift, footprint, fill), the horizontal
  levels, the fixtures on the front and the top, the colours, the wall behind, and the room
  around it (``room_context``);
- ``LargeObjectClassifier``: scikit-learn's shape (constructor stores, ``fit`` returns self,
  ``predict`` answers types);
- ``label(draft, ...)``: types and then parts (``articulate``) of every object of a draft;
- ``classifier()``: the model from the model store (``mapdraft.joblib``), trained when missing
  or stale on the drafts of the true-pose maps (hearth/mapping/true_pose_map.py) of generated
  homes ``TRAIN_SEEDS`` (never a benchmark seed), with its training configuration.
"""
from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin

from hearth.perception.semantic_map import Draft, ObjectDraft, articulate, handle_rows

#: Training homes of the classifier: never the benchmark's seeds (100.. report, 0..99 tune).
TRAIN_SEEDS = tuple(range(1000, 1041))
CLASSIFIER_VERSION = 3


FEATURES = (
    # the box
    "height", "z0", "long", "short", "front", "side", "area", "fill", "n_levels",
    "top_level_frac", "wall_distance", "front_flat", "hv_ratio",
    # the fixtures on the front and the top
    "n_handles", "n_vertical", "n_horizontal", "n_knobs_front", "n_knobs_top", "handle_z_max",
    "handle_len_max", "handle_rows", "handles_in_row", "handle_edge", "handle_z_rel",
    "handle_len_rel", "knob_z_rel", "knob_span_rel",
    # the colours: the whole, the top (a hob's black plate), the front against the sides
    "r", "g", "b", "top_dark", "colour_std", "top_minus_side", "front_minus_side",
    # the room around it (Rusu's CRF looks at its neighbours; this is their geometry, the
    # classifier's second stage adds their likely types)
    "room_area", "room_objects", "room_knobbed", "room_tall", "room_low_tables",
    "room_mid_tables", "room_small", "room_handles")


def room_context(draft_objects: list, obj: ObjectDraft, rooms: list) -> list[float]:
    """The room features of ``obj`` from the other objects' geometry: its room's area, how
    many other objects stand in it, how many carry two knobs or more, how many are over
    1.5 m tall, how many are tables (no handle, a level at the top) under 0.6 m and between
    0.6 and 0.9 m, how many are small (under 0.25 m^2: chairs, bedside tables), and the
    handles on them all."""
    others = [o for o in draft_objects if o.room == obj.room and o is not obj]
    room = rooms[obj.room]

    def handles(o):
        return sum(f.kind == "handle" for f in o.fixtures)

    tables = [o for o in others if not handles(o) and o.size_x * o.size_y > 0.25]
    return [room.size_x * room.size_y, len(others),
            sum(1 for o in others if sum(f.kind == "knob" for f in o.fixtures) >= 2),
            sum(1 for o in others if o.z1 > 1.5),
            sum(1 for o in tables if o.z1 < 0.6), sum(1 for o in tables if 0.6 <= o.z1 < 0.9),
            sum(1 for o in others if o.size_x * o.size_y < 0.25),
            sum(handles(o) for o in others)]


def _rows(handles: list) -> list[list]:
    """Handles grouped into rows (centres within 15 cm in height), lowest first."""
    return handle_rows(sorted(handles, key=lambda f: f.v))


def object_features(points_map: np.ndarray, normals_map: np.ndarray, colors: np.ndarray,
                    obj: ObjectDraft, context: list[float]) -> np.ndarray:
    """The feature vector (``FEATURES``) of an object draft with its front chosen (metres,
    colours 0..1); ``context``: its ``room_context``."""
    P, N, C = (np.asarray(a, float)[obj.index] for a in (points_map, normals_map, colors))
    handles = [f for f in obj.fixtures if f.kind == "handle" and f.side == 0]
    knobs_f = [f for f in obj.fixtures if f.kind == "knob" and f.side == 0]
    knobs_t = [f for f in obj.fixtures if f.kind == "knob" and f.side == 4]
    horiz = N[:, 2] > 0.9
    top = P[:, 2] > obj.z1 - 0.03
    loc = obj.to_local(P[:, :2])
    front_pts = np.abs(loc[:, 0] - obj.size_x / 2) < 0.04
    front_flat = float(np.mean(np.abs(loc[front_pts, 0] - obj.size_x / 2) < 0.01)) if front_pts.any() else 0.0
    sides = (np.abs(np.abs(loc[:, 1]) - obj.size_y / 2) < 0.03) & ~front_pts & ~top
    mean = C.mean(0)
    top_c = C[top].mean(0) if top.any() else mean
    side_c = C[sides].mean(0) if sides.sum() > 20 else mean
    front_c = C[front_pts & ~top].mean(0) if (front_pts & ~top).sum() > 20 else mean
    height = max(obj.z1 - obj.z0, 0.05)
    half_w = max(obj.size_y / 2, 0.05)
    rows = _rows(handles)
    # a door's handle stands near the edge away from its hinge, a drawer's in the middle
    edge = float(np.mean([abs(f.u) / half_w for f in handles])) if handles else 0.0
    kv = [f.v for f in knobs_f]
    ku = [f.u for f in knobs_f + knobs_t]
    return np.array([
        obj.z1, obj.z0, max(obj.size_x, obj.size_y), min(obj.size_x, obj.size_y), obj.size_x,
        obj.size_y, obj.size_x * obj.size_y, obj.fill, len(obj.levels),
        float(np.mean(top[horiz])) if horiz.any() else 0.0, min(obj.wall_distance, 2.0),
        front_flat, float(horiz.mean()),
        len(handles), sum(f.vertical for f in handles), sum(not f.vertical for f in handles),
        len(knobs_f), len(knobs_t),
        max((f.v for f in handles), default=0.0), max((f.length for f in handles), default=0.0),
        len(rows), max((len(r) for r in rows), default=0), edge,
        (max(f.v for f in handles) - obj.z0) / height if handles else 0.0,
        max(f.length for f in handles) / (2 * half_w) if handles else 0.0,
        (float(np.mean(kv)) - obj.z0) / height if kv else 0.0,
        float(np.ptp(ku)) / (2 * half_w) if len(ku) > 1 else 0.0,
        *mean, float(top_c.mean()), float(C.std(0).mean()),
        float(top_c.mean() - side_c.mean()), float(front_c.mean() - side_c.mean()),
        *context])


def _neighbour_sums(proba: np.ndarray, rooms: list) -> np.ndarray:
    """Per object, the sum of the class probabilities of the other objects in its room."""
    out = np.zeros_like(proba)
    keys = np.array([hash(r) for r in rooms])
    for k in np.unique(keys):
        idx = np.flatnonzero(keys == k)
        total = proba[idx].sum(0)
        out[idx] = total - proba[idx]
    return out


class LargeObjectClassifier(ClassifierMixin, BaseEstimator):
    """Types of large objects from ``object_features``: a random forest, and (``neighbours``,
    when ``fit`` is given each sample's room) a second forest that also sees the summed
    first-stage class probabilities of the other objects in the same room, the part of
    Rusu's CRF that makes a two-door cupboard among ovens a kitchen cupboard and the same
    carcass beside a coffee table a sideboard (stacking: the second forest is trained on
    the first stage's out-of-fold probabilities, folds by home).

    scikit-learn's shape: the constructor stores parameters, ``fit`` returns self,
    ``predict`` answers types, ``predict_proba`` per ``classes_``. ``rooms``: one hashable
    per sample naming its room (samples of different homes never share one); for
    ``fit`` a (home, room) pair, the home naming the fold."""

    def __init__(self, n_estimators: int = 300, min_samples_leaf: int = 1,
                 neighbours: bool = True, folds: int = 5, random_state: int = 0):
        self.n_estimators = n_estimators
        self.min_samples_leaf = min_samples_leaf
        self.neighbours = neighbours
        self.folds = folds
        self.random_state = random_state

    def _forest(self):
        from sklearn.ensemble import RandomForestClassifier
        return RandomForestClassifier(
            n_estimators=self.n_estimators, min_samples_leaf=self.min_samples_leaf,
            class_weight="balanced", random_state=self.random_state)

    def fit(self, X, y, rooms=None) -> "LargeObjectClassifier":
        X, y = np.asarray(X, float), np.asarray(list(y))
        self.forest_ = self._forest().fit(X, y)
        self.classes_ = self.forest_.classes_
        self.second_ = None
        homes = [r[0] for r in rooms] if rooms is not None else []
        if self.neighbours and rooms is not None and len(set(homes)) >= 2:
            from sklearn.model_selection import GroupKFold
            oof = np.zeros((len(X), len(self.classes_)))
            for tr, te in GroupKFold(n_splits=min(self.folds, len(set(homes)))).split(X, y, homes):
                f = self._forest().fit(X[tr], y[tr])
                cols = np.searchsorted(self.classes_, f.classes_)
                oof[np.ix_(te, cols)] = f.predict_proba(X[te])
            Z = np.hstack([X, _neighbour_sums(oof, list(rooms))])
            self.second_ = self._forest().fit(Z, y)
        return self

    def predict_proba(self, X, rooms=None) -> np.ndarray:
        """Class probabilities; with ``rooms`` (one per row: the rows of one room share a
        value) the second stage's."""
        from sklearn.utils.validation import check_is_fitted
        check_is_fitted(self, "forest_")
        X = np.atleast_2d(np.asarray(X, float))
        p = self.forest_.predict_proba(X)
        if self.second_ is not None and rooms is not None:
            p = self.second_.predict_proba(np.hstack([X, _neighbour_sums(p, list(rooms))]))
        return p

    def predict(self, X, rooms=None) -> np.ndarray:
        return self.classes_[np.argmax(self.predict_proba(X, rooms), axis=1)]


def label(draft: Draft, points_map, normals_map, colors, classifier: "LargeObjectClassifier",
          min_confidence: float = 0.35) -> Draft:
    """Stages 4-5: each object's type (``classifier``) and parts; an object the forest is
    unsure of (top probability under ``min_confidence``) keeps its best type and is listed in
    ``unlabelled``."""
    if not draft.objects:
        return draft
    X = np.array([object_features(points_map, normals_map, colors, o,
                                  room_context(draft.objects, o, draft.rooms))
                  for o in draft.objects])
    proba = classifier.predict_proba(X, rooms=[o.room for o in draft.objects])
    for o, p in zip(draft.objects, proba):
        k = int(np.argmax(p))
        o.type, o.confidence = str(classifier.classes_[k]), float(p[k])
        if o.confidence < min_confidence:
            draft.unlabelled.append((o, f"type unsure: {o.type} at {o.confidence:.2f}"))
        o.parts = articulate(o)
    return draft


# -- training and the model store --------------------------------------------------------------

def training_samples(seeds=TRAIN_SEEDS, progress=None):
    """(X, y, rooms) of the drafted objects of generated homes ``seeds`` (their true-pose
    maps); ``rooms``: (seed, room index) per object."""
    from hearth.perception.semantic_map import draft_geometry
    from hearth.worldmodel.homegen import HomeConfig
    from hearth.mapping.true_pose_map import cached_fused
    from hearth.mapping.truth import label_of, truth_objects
    X, y, rooms = [], [], []
    for i, seed in enumerate(seeds):
        world, pcd = cached_fused(seed, HomeConfig(rooms=(2, 3)))
        P, N, C = np.asarray(pcd.points), np.asarray(pcd.normals), np.asarray(pcd.colors)
        d = draft_geometry(P, N)
        truth = truth_objects(world)
        for o in d.objects:
            X.append(object_features(P, N, C, o, room_context(d.objects, o, d.rooms)))
            y.append(label_of(o, truth))
            rooms.append((seed, o.room))
        if progress:
            progress(f"training home {seed}: {len(d.objects)} objects ({i + 1}/{len(seeds)})")
    return np.array(X), y, rooms


def _configuration() -> dict:
    from dataclasses import asdict
    from hearth.perception.semantic_map import DraftConfig
    from hearth.worldmodel.homegen import GENERATOR_VERSION
    from hearth.mapping.true_pose_map import TruePoseMapConfig
    return dict(version=CLASSIFIER_VERSION, seeds=list(TRAIN_SEEDS), features=list(FEATURES),
                draft=asdict(DraftConfig()), fusion=asdict(TruePoseMapConfig()),
                generator=GENERATOR_VERSION, rooms=[2, 3])


def classifier(retrain: bool = True, progress=None):
    """The large-object classifier from the model store (``mapdraft.joblib``), trained now
    on the true-pose maps of ``TRAIN_SEEDS`` when missing or stale."""
    from hearth.worldmodel import model_store

    def train():
        X, y, rooms = training_samples(progress=progress)
        return LargeObjectClassifier().fit(X, y, rooms=rooms)
    try:
        clf, info = model_store.load_or_train("mapdraft", _configuration(), train,
                                              retrain=retrain)
    except model_store.ModelUnavailable as err:
        from hearth.perception.errors import PerceptionError
        raise PerceptionError(f"large-object classifier: {err}; run `hearth bench "
                              "mapping_draft` once to train it") from None
    return clf
