"""Stiffness from force–displacement samples: models, fits, model selection, batch fitting."""
from palpd.stiffness.fit import LinearFit, ModelFit, fit_linear, fit_model, load_solvers
from palpd.stiffness.models import MODELS
from palpd.stiffness.samples import REASONS, FitRejected
from palpd.stiffness.selection import CRITERIA, SELECT, StiffnessResult, fit_stiffness

__all__ = ["CRITERIA", "MODELS", "REASONS", "SELECT", "FitRejected", "LinearFit", "ModelFit", "StiffnessResult",
           "fit_linear", "fit_model", "fit_stiffness", "load_solvers"]
