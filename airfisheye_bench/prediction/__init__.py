"""``airfisheye-predict``: a trained model (checkpoint or ONNX) run on unlabelled footage (:mod:`.predict`), the
frames and videos it reads (:mod:`.footage`) and each frame's camera and inputs (:mod:`.footage_inputs`).
Nothing is imported here."""
