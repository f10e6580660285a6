"""Encoder-side analysis of seed 003 (Repeated Motion Analysis), the groundwork of codec ``rma``.

Not a codec yet: these modules turn motions into the data the codec will code and measure how
compact it can be.

- :mod:`.preprocess`: root alignment (§3) and compact virtual markers (Fig. 2b), with the inverse.
- :mod:`.segment`: PPCA cuts forward and backward (§4.1) and normalized-cut grouping (eq. 1).
- :mod:`.pca`: per-group frame PCA by variance fraction or by a max-error target (§5.4 bits).
- :mod:`.repeats`: self-distance plots in tiles, similar-posture paths, greedy primary /
  repeated / unique clips (§4.2, eq. 2-5).
"""
