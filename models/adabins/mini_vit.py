"""The mini-ViT of AdaBins: global bin widths and per-pixel range-attention maps from decoder features.

Follows ``models/miniViT.py`` and ``models/layers.py`` of the official code (shariqfarooq123/AdaBins), with one
change: the official positional encodings are a learned ``500 x E`` table indexed by the flattened patch index,
which limits the input to 500 patches (e.g. 640x640) and ties positions to the image width. Here they are a learned
2-D grid that is bilinearly resized to the actual patch grid, so any input size works (as in ViT fine-tuning at
a new resolution) and the export stays shape-generic.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

BIN_NORMS = ("linear", "softmax", "sigmoid")


class PatchTransformerEncoder(nn.Module):
    """Patch embedding (a ``patch_size`` strided conv) + positional encoding + transformer encoder.

    Args:
        in_channels: channels of the input feature map.
        patch_size: side of the square patches (16 in AdaBins).
        embedding_dim: token size E (128).
        num_heads: attention heads (4).
        num_layers: transformer layers (4).
        dim_feedforward: hidden size of the transformer MLP (1024).
        pos_grid_size: side of the learned positional-encoding grid (16 = the patch grid of a 512x512 input).

    Returns (forward):
        Tokens ``[S, B, E]`` (sequence first, as the official code), S = number of patches.
    """

    def __init__(
        self,
        in_channels: int,
        patch_size: int = 16,
        embedding_dim: int = 128,
        num_heads: int = 4,
        num_layers: int = 4,
        dim_feedforward: int = 1024,
        pos_grid_size: int = 16,
    ) -> None:
        super().__init__()
        layer = nn.TransformerEncoderLayer(embedding_dim, num_heads, dim_feedforward=dim_feedforward)
        self.transformer_encoder = nn.TransformerEncoder(
            layer, num_layers=num_layers, enable_nested_tensor=False
        )
        self.embedding_convPxP = nn.Conv2d(
            in_channels, embedding_dim, kernel_size=patch_size, stride=patch_size
        )
        # Uniform [0, 1) initialisation, as the official table.
        self.positional_encodings = nn.Parameter(torch.rand(1, embedding_dim, pos_grid_size, pos_grid_size))

    def forward(self, x: Tensor) -> Tensor:
        embeddings = self.embedding_convPxP(x)  # [B, E, h, w]
        # Resizing to the same size is the identity (align_corners=False, scale 1), so no shape branch is needed.
        pos = F.interpolate(
            self.positional_encodings, size=embeddings.shape[-2:], mode="bilinear", align_corners=False
        )
        embeddings = (embeddings + pos).flatten(2).permute(2, 0, 1)  # [S, B, E]
        return self.transformer_encoder(embeddings)


class PixelWiseDotProduct(nn.Module):
    """Dot product of every pixel's feature vector with each query: ``[B, C, H, W] x [B, Q, C] -> [B, Q, H, W]``."""

    def forward(self, x: Tensor, queries: Tensor) -> Tensor:
        # A batched matmul rather than einsum: ONNX Runtime runs MatMul much faster than Einsum.
        return torch.matmul(queries, x.flatten(2)).unflatten(2, x.shape[-2:])


class MiniViT(nn.Module):
    """AdaBins' ``mViT``: normalised bin widths ``[B, n_bins]`` and range-attention maps ``[B, Q, H, W]``.

    Token 0 goes through an MLP regressor to the bin widths; tokens ``1..Q`` are the queries dotted with a 3x3
    conv of the input features.

    Args:
        in_channels: channels of the decoder features (128).
        n_query_channels: Q, number of range-attention maps (128). The input needs at least ``Q + 1`` patches.
        patch_size, embedding_dim, num_heads, num_layers, dim_feedforward, pos_grid_size: see
            :class:`PatchTransformerEncoder`.
        n_bins: number of bins (256 in the paper).
        norm: bin-width normalisation, ``"linear"`` (``relu(y) + 0.1`` then divide by the sum; the default),
            ``"softmax"`` or ``"sigmoid"`` (then divide by the sum).

    Example:
        >>> vit = MiniViT(8, n_query_channels=4, patch_size=4, n_bins=10, embedding_dim=8, num_heads=2)
        >>> widths, maps = vit(torch.randn(2, 8, 16, 16))
        >>> widths.shape, maps.shape, bool(torch.allclose(widths.sum(1), torch.ones(2)))
        (torch.Size([2, 10]), torch.Size([2, 4, 16, 16]), True)
    """

    def __init__(
        self,
        in_channels: int,
        n_query_channels: int = 128,
        patch_size: int = 16,
        n_bins: int = 256,
        embedding_dim: int = 128,
        num_heads: int = 4,
        num_layers: int = 4,
        dim_feedforward: int = 1024,
        pos_grid_size: int = 16,
        norm: str = "linear",
    ) -> None:
        super().__init__()
        if norm not in BIN_NORMS:
            raise ValueError(f"norm must be one of {BIN_NORMS}, got {norm!r}")
        self.norm = norm
        self.n_query_channels = n_query_channels
        self.patch_size = patch_size
        self.patch_transformer = PatchTransformerEncoder(
            in_channels, patch_size, embedding_dim, num_heads, num_layers, dim_feedforward, pos_grid_size
        )
        self.dot_product_layer = PixelWiseDotProduct()
        self.conv3x3 = nn.Conv2d(in_channels, embedding_dim, kernel_size=3, stride=1, padding=1)
        self.regressor = nn.Sequential(
            nn.Linear(embedding_dim, 256),
            nn.LeakyReLU(),
            nn.Linear(256, 256),
            nn.LeakyReLU(),
            nn.Linear(256, n_bins),
        )

    def forward(self, x: Tensor) -> tuple[Tensor, Tensor]:
        patches = (x.shape[-2] // self.patch_size) * (x.shape[-1] // self.patch_size)
        if patches < self.n_query_channels + 1:
            raise ValueError(
                f"the mini-ViT needs at least n_query_channels + 1 = {self.n_query_channels + 1} patches of "
                f"{self.patch_size} px, but features of {x.shape[-2]}x{x.shape[-1]} give {patches}; "
                "use a larger input, a smaller patch_size or fewer n_query_channels"
            )
        tokens = self.patch_transformer(x)  # [S, B, E]
        regression_head = tokens[0]  # [B, E]
        queries = tokens[1 : self.n_query_channels + 1].permute(1, 0, 2)  # [B, Q, E]
        range_attention_maps = self.dot_product_layer(self.conv3x3(x), queries)
        return normalize_bin_widths(self.regressor(regression_head), self.norm), range_attention_maps


def normalize_bin_widths(y: Tensor, norm: str) -> Tensor:
    """Positive bin widths summing to 1 along dim 1, with AdaBins' normalisations.

    Example:
        >>> normalize_bin_widths(torch.tensor([[-1.0, 0.3]]), "linear")
        tensor([[0.2000, 0.8000]])
    """
    if norm == "linear":
        y = torch.relu(y) + 0.1  # the 0.1 keeps every bin open
    elif norm == "softmax":
        return torch.softmax(y, dim=1)
    elif norm == "sigmoid":
        y = torch.sigmoid(y)
    else:
        raise ValueError(f"norm must be one of {BIN_NORMS}, got {norm!r}")
    return y / y.sum(dim=1, keepdim=True)
