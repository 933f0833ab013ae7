#!/usr/bin/env python3
"""The OpenCV peer of `cargo xtask pose --accuracy`: SIFT, Lowe's ratio test at 0.8,
findEssentialMat with RANSAC, then recoverPose, on the pairs of a JSON file written by the
command (`pip install opencv-python-headless`):

    python3 xtask/scripts/pose_opencv.py pairs.json out.json

pairs.json: [{"a": PATH, "b": PATH, "k1": [9 row-major], "k2": [9 row-major]}, ...], with K in
pixels for OpenCV's pixel centres (integers). out.json: one entry per pair, {"r": [9 row-major]
src_from_ref, "t": [3], "seconds": s} or {"error": "...", "seconds": s}.
"""
import json
import sys
import time

import cv2
import numpy as np

pairs = json.load(open(sys.argv[1]))
sift = cv2.SIFT_create()
matcher = cv2.BFMatcher(cv2.NORM_L2)
out = []
for p in pairs:
    t0 = time.perf_counter()
    try:
        a = cv2.imread(p["a"], cv2.IMREAD_GRAYSCALE)
        b = cv2.imread(p["b"], cv2.IMREAD_GRAYSCALE)
        ka, da = sift.detectAndCompute(a, None)
        kb, db = sift.detectAndCompute(b, None)
        good = [m for m, n in matcher.knnMatch(da, db, k=2) if m.distance < 0.8 * n.distance]
        x1 = np.float64([ka[m.queryIdx].pt for m in good])
        x2 = np.float64([kb[m.trainIdx].pt for m in good])
        k1 = np.array(p["k1"], dtype=np.float64).reshape(3, 3)
        k2 = np.array(p["k2"], dtype=np.float64).reshape(3, 3)
        # Both views to normalised coordinates, so one identity camera serves both.
        n1 = cv2.undistortPoints(x1.reshape(-1, 1, 2), k1, None)
        n2 = cv2.undistortPoints(x2.reshape(-1, 1, 2), k2, None)
        f = (k1[0, 0] + k1[1, 1] + k2[0, 0] + k2[1, 1]) / 4
        e, mask = cv2.findEssentialMat(n1, n2, np.eye(3), method=cv2.RANSAC, prob=0.999, threshold=1.0 / f)
        _, r, t, _ = cv2.recoverPose(e[:3], n1, n2, np.eye(3), mask=mask)
        out.append({"r": r.reshape(-1).tolist(), "t": t.reshape(-1).tolist(),
                    "seconds": time.perf_counter() - t0})
    except Exception as ex:  # a failed pair is a result, not a crash
        out.append({"error": str(ex), "seconds": time.perf_counter() - t0})
json.dump(out, open(sys.argv[2], "w"))
