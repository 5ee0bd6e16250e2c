"""Loop detection: a bag of binary words over keyframes, then a geometric check.

The vocabulary is learned from the sequence's own first keyframes (k-majority clustering of ORB
descriptors, the binary analogue of k-means that DBoW2's vocabularies are built with), because no
pre-trained vocabulary can be downloaded here; a word is the nearest centre in Hamming distance.
Keyframes are tf-idf vectors, compared with DBoW2's L1 score. A keyframe far enough back in time
that scores at least ``RELATIVE_SCORE`` of the query's own recent neighbours' lowest score becomes
a candidate; it is a loop when the previous keyframe voted for the same place (within a few
keyframes) and PnP RANSAC finds ``min_inliers`` of the candidate's 3D points in the query.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from workloads.slam import sim3
from workloads.slam.camera import Intrinsics
from workloads.slam.geometry import from_rvec, inverse

RELATIVE_SCORE = 0.75
RATIO = 0.8


@dataclass(frozen=True)
class LoopKeyframe:
    id: int
    uv: np.ndarray  # (N, 2)
    desc: np.ndarray  # (N, 32)
    points: np.ndarray  # (N, 3) in the keyframe's camera frame, NaN where the feature has no 3D point
    # Monocular: (N,) True where the point was triangulated by this keyframe itself, just made and
    # not yet refined by the keyframes after it. As a loop's query, a keyframe's scale is read from
    # its other points only: on bigloop-1 its own came out at 0.30 of the true depth (median, 0.22
    # at p10) where the points it tracked sat at 0.40 and the map's scale was 0.41 (measured against
    # the rendered depth), which gave the loop a scale of 1.44 where the truth was 1.04.
    fresh: np.ndarray | None = None


@dataclass(frozen=True)
class Loop:
    query: int
    match: int
    relative: np.ndarray  # the query keyframe's pose in the matched keyframe's frame
    inliers: int
    score: float
    # Monocular: the query keyframe's frame in the matched one's as a similarity, whose scale is the
    # matched map's units per query-map unit (:func:`workloads.slam.sim3.from_loop`); RGB-D: None.
    similarity: np.ndarray | None = None
    scale_pairs: int = 0  # inliers whose query feature has a map point too (what the scale is read from)


class Vocabulary:
    def __init__(self, words: np.ndarray, idf: np.ndarray) -> None:
        self.words, self.idf = words, idf
        self._matcher = cv2.BFMatcher(cv2.NORM_HAMMING)

    @classmethod
    def train(cls, documents: list[np.ndarray], *, size: int = 500, iterations: int = 4, seed: int = 0) -> Vocabulary:
        desc = np.concatenate(documents)
        rng = np.random.default_rng(seed)
        words = desc[rng.choice(len(desc), size=min(size, len(desc)), replace=False)].copy()
        bits = np.unpackbits(desc, axis=1).astype(np.float32)
        vocab = cls(words, np.ones(len(words)))
        for _ in range(iterations):
            assign = vocab.quantise(desc)
            counts = np.zeros((len(words), bits.shape[1]), np.float32)
            np.add.at(counts, assign, bits)
            members = np.bincount(assign, minlength=len(words))
            used = members > 0
            words[used] = np.packbits(counts[used] / members[used, None] > 0.5, axis=1)
            vocab = cls(words, np.ones(len(words)))
        present = np.zeros(len(words))
        for doc in documents:
            present[np.unique(vocab.quantise(doc))] += 1
        return cls(words, np.log(len(documents) / np.maximum(present, 1.0)) + 1e-3)

    def quantise(self, desc: np.ndarray) -> np.ndarray:
        return np.array([m.trainIdx for m in self._matcher.match(desc, self.words)], np.int64)

    def vector(self, desc: np.ndarray) -> np.ndarray:
        v = np.bincount(self.quantise(desc), minlength=len(self.words)) * self.idf
        total = v.sum()
        return (v / total if total > 0 else v).astype(np.float32)


def score(v: np.ndarray, others: np.ndarray) -> np.ndarray:
    """DBoW2's L1 score, 1 for the same bag of words, 0 for disjoint ones."""
    return 1.0 - 0.5 * np.abs(others - v).sum(axis=-1)


class LoopDetector:
    """Fed every keyframe in order; answers a :class:`Loop` when one closes."""

    def __init__(self, intrinsics: Intrinsics, *, train_after: int = 10, min_gap: int = 20, min_inliers: int = 40,
                 words: int = 500) -> None:
        self.intrinsics, self.train_after = intrinsics, train_after
        self.min_gap, self.min_inliers = min_gap, min_inliers
        self.words = words
        self.keyframes: list[LoopKeyframe] = []
        self.vectors: list[np.ndarray] = []
        self.vocabulary: Vocabulary | None = None
        self._previous_vote: int | None = None
        self._quiet_until = -1
        self._matcher = cv2.BFMatcher(cv2.NORM_HAMMING)

    def add(self, kf: LoopKeyframe) -> Loop | None:
        self.keyframes.append(kf)
        if self.vocabulary is None:
            if len(self.keyframes) < self.train_after:
                return None
            self.vocabulary = Vocabulary.train([k.desc for k in self.keyframes], size=self.words)
            self.vectors = [self.vocabulary.vector(k.desc) for k in self.keyframes]
            return None
        self.vectors.append(self.vocabulary.vector(kf.desc))
        position = len(self.keyframes) - 1
        eligible = position - self.min_gap
        if eligible <= 0 or kf.id < self._quiet_until:
            self._previous_vote = None
            return None
        vectors = np.array(self.vectors)
        neighbours = score(vectors[position], vectors[max(0, position - 3):position])
        scores = score(vectors[position], vectors[:eligible])
        best = int(np.argmax(scores))
        if scores[best] < RELATIVE_SCORE * neighbours.min():
            self._previous_vote = None
            return None
        vote, previous = self.keyframes[best].id, self._previous_vote
        self._previous_vote = vote
        if previous is None or abs(previous - vote) > 3:
            return None
        loop = self._verify(kf, self.keyframes[best], float(scores[best]))
        if loop is not None:
            self._quiet_until = kf.id + self.min_gap // 2
        return loop

    def _verify(self, query: LoopKeyframe, match: LoopKeyframe, bow_score: float) -> Loop | None:
        has_point = ~np.isnan(match.points[:, 0])
        if has_point.sum() < self.min_inliers:
            return None
        train_idx = np.flatnonzero(has_point)
        pairs = self._matcher.knnMatch(query.desc, match.desc[train_idx], k=2)
        good = [p[0] for p in pairs if len(p) == 2 and p[0].distance < RATIO * p[1].distance]
        if len(good) < self.min_inliers:
            return None
        obj = match.points[train_idx[[m.trainIdx for m in good]]]
        img = query.uv[[m.queryIdx for m in good]].astype(np.float64)
        ok, rvec, tvec, inliers = cv2.solvePnPRansac(obj, img, self.intrinsics.matrix(), None, iterationsCount=200,
                                                     reprojectionError=3.0, confidence=0.999)
        if not ok or inliers is None or len(inliers) < self.min_inliers:
            return None
        query_from_match = from_rvec(rvec, tvec)
        inl = inliers.ravel()
        query_idx = np.array([good[int(i)].queryIdx for i in inl], np.int64)
        in_query = query.points[query_idx].copy()
        if query.fresh is not None:
            in_query[query.fresh[query_idx]] = np.nan
        similarity, scale_pairs = sim3.from_loop(query_from_match, in_query, obj[inl])
        return Loop(query.id, match.id, inverse(query_from_match), len(inliers), bow_score, similarity, scale_pairs)
