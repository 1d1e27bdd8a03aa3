"""Model settings small enough for a unit test (seconds on a CPU, no download)."""

from __future__ import annotations

#: The three zoo models with a ResNet18 encoder, as small as they get (keyword arguments of each model).
TINY = {
    "deeplabv3plus": {"encoder_name": "resnet18", "num_classes": 3, "decoder_channels": 16},
    "adabins": {
        "encoder_name": "resnet18",
        "n_bins": 8,
        "decoder_features": 32,
        "decoder_out_channels": 16,
        "patch_size": 4,
        "embedding_dim": 16,
        "num_heads": 2,
        "num_layers": 1,
        "dim_feedforward": 16,
        "n_query_channels": 8,
        "pos_grid_size": 4,
    },
    "nlspn": {"encoder_name": "resnet18", "prop_steps": 1},
}
