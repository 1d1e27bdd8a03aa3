"""LightningDataModules and datasets for the AirFisheye layout (synthetic and real releases alike)."""

from datamodules.airfisheye import AirFisheyeDataModule
from datamodules.augment import FisheyeAugment
from datamodules.dataset import AirFisheyeDataset, CameraConfig, collate

__all__ = ["AirFisheyeDataModule", "AirFisheyeDataset", "CameraConfig", "FisheyeAugment", "collate"]
