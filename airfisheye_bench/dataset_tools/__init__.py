"""The commands over a dataset folder: ``airfisheye-inspect`` (:mod:`.inspect`, :mod:`.inspect_source`,
:mod:`.inspect_scans`) and ``airfisheye-transcode`` (:mod:`.transcode`). Each is imported by its console entry
point when called; nothing is imported here."""
