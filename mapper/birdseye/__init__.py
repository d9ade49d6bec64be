"""Seed 004's camera map (Rettkowski et al., §V): bird's-eye view, HSV thresholds, stitching.

A colour image of the floor ahead is dewarped by a homography from a trapezoid in the image
to a rectangle (``view.py``), thresholded in HSV into a binary obstacle map and a target mask
(obstacles purple, the target green), and, when the target is not in view, widened by
stitching up to five images taken while turning (``stitch.py``). All image work is OpenCV's.
"""
