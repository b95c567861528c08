"""Placeholder: the simulation helper owns this module (illuminance, sensors, jobs)."""

from fastapi import APIRouter

router = APIRouter()
