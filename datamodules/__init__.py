"""LightningDataModules and datasets for the AirFisheye layout (synthetic and real releases alike)."""

from datamodules.augment import FisheyeAugment
from datamodules.datamodule import AirFisheyeDataModule
from datamodules.dataset import AirFisheyeDataset, CameraConfig, collate

__all__ = ["AirFisheyeDataModule", "AirFisheyeDataset", "CameraConfig", "FisheyeAugment", "collate"]
