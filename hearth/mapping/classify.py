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

from hearth.perception.semantic_map import Draft, ObjectDraft, articulate

#: Training homes of the classifier: never the benchmark's seeds (100.. report, 0..99 tune).
TRAIN_SEEDS = tuple(range(1000, 1019))
CLASSIFIER_VERSION = 2


FEATURES = ("height", "z0", "long", "short", "front", "side", "area", "fill", "n_levels",
            "top_level_frac", "n_handles", "n_vertical", "n_horizontal", "n_knobs_front",
            "n_knobs_top", "handle_z_max", "handle_len_max", "wall_distance", "r", "g", "b",
            "top_dark", "colour_std", "front_flat", "hv_ratio",
            # the room around it (Rusu's CRF looks at neighbours; this is the cheap part)
            "room_area", "room_objects", "room_knobbed", "room_tall")


def room_context(draft_objects: list, obj: ObjectDraft, rooms: list) -> list[float]:
    """The room features of ``obj``: its room's area, how many other objects stand in it,
    how many of those carry two knobs or more, how many are over 1.5 m tall."""
    others = [o for o in draft_objects if o.room == obj.room and o is not obj]
    room = rooms[obj.room]
    return [room.size_x * room.size_y, len(others),
            sum(1 for o in others if sum(f.kind == "knob" for f in o.fixtures) >= 2),
            sum(1 for o in others if o.z1 > 1.5)]


def object_features(points_map: np.ndarray, normals_map: np.ndarray, colors: np.ndarray,
                    obj: ObjectDraft, context: list[float]) -> np.ndarray:
    """The feature vector (``FEATURES``) of an object draft with its front chosen;
    ``context``: its ``room_context``."""
    P, N, C = (np.asarray(a, float)[obj.index] for a in (points_map, normals_map, colors))
    handles = [f for f in obj.fixtures if f.kind == "handle" and f.side == 0]
    knobs_f = [f for f in obj.fixtures if f.kind == "knob" and f.side == 0]
    knobs_t = [f for f in obj.fixtures if f.kind == "knob" and f.side == 4]
    horiz = N[:, 2] > 0.9
    top = P[:, 2] > obj.z1 - 0.03
    loc = obj.to_local(P[:, :2])
    front_pts = np.abs(loc[:, 0] - obj.size_x / 2) < 0.04
    front_flat = float(np.mean(np.abs(loc[front_pts, 0] - obj.size_x / 2) < 0.01)) if front_pts.any() else 0.0
    top_c = C[top].mean(0) if top.any() else C.mean(0)
    return np.array([
        obj.z1, obj.z0, max(obj.size_x, obj.size_y), min(obj.size_x, obj.size_y), obj.size_x,
        obj.size_y, obj.size_x * obj.size_y, obj.fill, len(obj.levels),
        float(np.mean(top[horiz])) if horiz.any() else 0.0,
        len(handles), sum(f.vertical for f in handles), sum(not f.vertical for f in handles),
        len(knobs_f), len(knobs_t),
        max((f.v for f in handles), default=0.0), max((f.length for f in handles), default=0.0),
        min(obj.wall_distance, 2.0), *C.mean(0), float(top_c.mean()), float(C.std(0).mean()),
        front_flat, float(horiz.mean()), *context])


class LargeObjectClassifier(ClassifierMixin, BaseEstimator):
    """A random forest over ``object_features`` (scikit-learn's shape: the constructor
    stores parameters, ``fit`` returns self, ``predict`` answers types, ``predict_proba``
    per ``classes_``)."""

    def __init__(self, n_estimators: int = 300, min_samples_leaf: int = 1, random_state: int = 0):
        self.n_estimators = n_estimators
        self.min_samples_leaf = min_samples_leaf
        self.random_state = random_state

    def fit(self, X, y) -> "LargeObjectClassifier":
        from sklearn.ensemble import RandomForestClassifier
        self.forest_ = RandomForestClassifier(
            n_estimators=self.n_estimators, min_samples_leaf=self.min_samples_leaf,
            class_weight="balanced", random_state=self.random_state).fit(np.asarray(X), list(y))
        self.classes_ = self.forest_.classes_
        return self

    def predict_proba(self, X) -> np.ndarray:
        from sklearn.utils.validation import check_is_fitted
        check_is_fitted(self, "forest_")
        return self.forest_.predict_proba(np.atleast_2d(np.asarray(X, float)))

    def predict(self, X) -> np.ndarray:
        return self.classes_[np.argmax(self.predict_proba(X), axis=1)]




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
    proba = classifier.predict_proba(X)
    for o, p in zip(draft.objects, proba):
        k = int(np.argmax(p))
        o.type, o.confidence = str(classifier.classes_[k]), float(p[k])
        if o.confidence < min_confidence:
            draft.unlabelled.append((o, f"type unsure: {o.type} at {o.confidence:.2f}"))
        o.parts = articulate(o)
    return draft


# -- training and the model store --------------------------------------------------------------

def training_samples(seeds=TRAIN_SEEDS, progress=None):
    """(X, y) of the drafted objects of generated homes ``seeds`` (their true-pose maps)."""
    from hearth.perception.semantic_map import draft_geometry
    from hearth.worldmodel.homegen import HomeConfig
    from hearth.mapping.true_pose_map import cached_fused
    from hearth.mapping.truth import label_of, truth_objects
    X, y = [], []
    for i, seed in enumerate(seeds):
        world, pcd = cached_fused(seed, HomeConfig(rooms=(2, 3)))
        P, N, C = np.asarray(pcd.points), np.asarray(pcd.normals), np.asarray(pcd.colors)
        d = draft_geometry(P, N)
        truth = truth_objects(world)
        for o in d.objects:
            X.append(object_features(P, N, C, o, room_context(d.objects, o, d.rooms)))
            y.append(label_of(o, truth))
        if progress:
            progress(f"training home {seed}: {len(d.objects)} objects ({i + 1}/{len(seeds)})")
    return np.array(X), y


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
        X, y = training_samples(progress=progress)
        return LargeObjectClassifier().fit(X, y)
    try:
        clf, info = model_store.load_or_train("mapdraft", _configuration(), train,
                                              retrain=retrain)
    except model_store.ModelUnavailable as err:
        from hearth.perception.errors import PerceptionError
        raise PerceptionError(f"large-object classifier: {err}; run `hearth bench "
                              "mapping_draft` once to train it") from None
    return clf
