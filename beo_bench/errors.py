"""Exceptions of the package: each names what was wrong and how to fix it.

Every error raised on bad input derives from :class:`BeoBenchError`, so callers can catch
the whole family; the specific classes also derive from the matching builtin
(``ValueError``, ``KeyError``, ``IndexError``) so generic handlers keep working.
"""

from __future__ import annotations


class BeoBenchError(Exception):
    """Base class of every error this package raises on bad input or state."""

    exit_code = 1
    """What the CLI exits with: 1 for a failure, 2 for a usage error (see UsageError)."""


class UnknownCategoryError(BeoBenchError, KeyError):
    """A category name that no registry or dataset knows."""

    exit_code = 2

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class InstanceIndexError(BeoBenchError, IndexError):
    """An instance index outside a split's range."""


class UnknownSplitError(BeoBenchError, ValueError):
    """A split name that is not one of the library's splits."""

    exit_code = 2


class InvalidKeyError(BeoBenchError, ValueError):
    """An instance key that cannot be parsed or resolved."""

    exit_code = 2


class UserDataError(BeoBenchError):
    """An error caused by the user's data or set-up, never by beo-bench: a mesh file, a
    dataset folder, the asset cache directory. The CLI exits 2 for it (as for a usage
    error: what must change is the input), and a worker process hands it to the driver as
    it is (:mod:`beo_bench.bench.pool`), so it is never reported as a bug in beo-bench."""

    exit_code = 2


class MeshError(UserDataError, ValueError):
    """A mesh that cannot be used as an object."""


class MeshLoadError(MeshError):
    """A mesh file that is missing, unreadable or corrupt."""


class CorruptMeshError(MeshLoadError):
    """A mesh file that parses but whose content is damaged, so that using it would give a
    wrong object rather than an error (see the two subclasses)."""


class NonFiniteMeshError(CorruptMeshError):
    """A mesh with NaN or infinite vertex coordinates. Readers drop such vertices with their
    faces, which used to surface much later as a misleading "not watertight"."""


class TruncatedMeshError(CorruptMeshError):
    """A mesh file that ends in the middle of a statement or whose faces index vertices
    that are not in the file: an interrupted download or copy. Repair would otherwise turn
    the remaining part into a plausible but partial object."""


class EmptyMeshError(MeshError):
    """A mesh with no faces or no volume."""


class TooManyFacesError(MeshError):
    """A mesh file with more faces than the face budget of a dataset check
    (:data:`beo_bench.objects.datasets.MAX_INPUT_FACES`, ``--max-faces``): loading and
    repairing a multi-million-face scan takes minutes and gigabytes, so it is refused
    before it is parsed, where its face count can be read from the file's header or lines."""

    faces: int | None = None
    """The file's face count (set where it is raised; not kept across processes)."""


class NonWatertightMeshError(MeshError):
    """A mesh that is not watertight and could not be repaired."""


class ImplausibleSizeError(MeshError):
    """A loaded mesh whose real-world size cannot be a tabletop object: smaller than the
    gripper can meaningfully hold or see, or too large to lie on the table in every pose.
    Usually the file's units were misread (a millimetre file taken as metres) or a
    normalised model was kept at its file scale; the message names the ``units=`` or
    ``size=`` option that fixes it."""


class DatasetLayoutError(UserDataError, ValueError):
    """A dataset folder that is missing, is no directory or does not have the expected
    layout."""


class DatasetTooLargeError(DatasetLayoutError):
    """A dataset folder whose scan passed its bound on the files and folders it visits
    (:data:`beo_bench.objects.datasets.walk.MAX_FILES`): usually ``--objects`` pointing at a home
    or root directory rather than at a dataset."""


class ManifestError(DatasetLayoutError):
    """A dataset's ``beo-bench.toml`` (per-class and per-file loading options) that cannot
    be used: not TOML, an unknown table or key, a bad value, or a class or file the dataset
    does not have. The message names the file and the key."""


class BadObjectsError(UserDataError, ValueError):
    """Files of a user's dataset that cannot be used as objects, found by the check before
    a command uses the dataset (:func:`beo_bench.objects.datasets.check_dataset`); the
    message lists each with what is wrong and the flag that fixes it."""


class BopFormatError(UserDataError, ValueError):
    """A BOP-format file (results CSV, dataset JSON, image) given to beo-bench that does not
    follow the format: the message names the file, the line or key, and what is wrong."""


class CacheDirError(UserDataError):
    """An asset cache (``$BEO_BENCH_CACHE``) that is not a directory, is not writable or has
    too little free space: found when a command starts, or when an entry cannot be written."""


class EnvConfigError(BeoBenchError, ValueError):
    """An environment setting that is unknown or impossible (raised at ``gym.make``)."""

    exit_code = 2


class ActionError(BeoBenchError, ValueError):
    """An action of the wrong shape, with NaN/inf, or out of reach or range."""


class ViewError(BeoBenchError, ValueError):
    """A perception input that cannot be used (wrong shape, empty mask, no valid depth)."""


class EstimateError(BeoBenchError, ValueError):
    """A backend's output that breaks the ``Estimate`` contract (shape, range, rotation)."""


class BackendError(BeoBenchError, KeyError):
    """An unknown backend name, or a second registration under a taken name."""

    exit_code = 2

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class CheckpointError(BeoBenchError, ValueError):
    """A trained model that is missing, corrupt, or made for other settings (categories,
    resolution, subspace, crop size) than the ones asked for."""


# -- added for the safety and integrity work: every failure the CLI reports has a class ----
class UsageError(BeoBenchError, ValueError):
    """A command-line argument, option value or setting that is out of range or malformed.
    The CLI exits with status 2 for it (as argparse does for its own usage errors)."""

    exit_code = 2


class InvalidNameError(UsageError):
    """A model, run or cache-kind name that is not a plain name (path separators, ``..``,
    an absolute path, or characters outside ``[A-Za-z0-9._-]``)."""


class TrainingInRunError(UsageError):
    """Backend options that select a model nobody trained (``--opt instances``, ``images``,
    ``epochs`` of ``hbeo`` and ``hbeo-mdn-*``; ``instances``, ``resolution`` of ``beo``).
    A run never trains a model. The
    message names the ``beo-bench train`` command, with the matching flags, that makes the
    model; the same options then load it."""

    @classmethod
    def of(cls, backend: str, options: dict[str, object], command: str) -> TrainingInRunError:
        """The error for ``backend`` given ``options`` (name -> value), whose model
        ``command`` trains."""
        opts = " ".join(f"--opt {k}={v}" for k, v in options.items())
        return cls(
            f"{backend} {opts}: no model is trained for these options, and a run never trains "
            f"one: train it first with `{command}`, then run again with the same options"
        )


class CorruptDataError(BeoBenchError, ValueError):
    """A file this package wrote earlier (cache entry, training shard, results file, run
    record) that is truncated or damaged. The message says whether it was rebuilt, skipped
    or must be deleted."""


class PluginError(BackendError):
    """A third-party backend plugin (entry point) that fails to import or register."""

    exit_code = 1


class ThresholdError(BeoBenchError):
    """A command that finished its work and found its results past a limit the user set:
    ``gate`` found a regression, or a run's failure rate is above ``--max-failure-rate``.
    The CLI exits with status 3 for it, so a CI job tells "worse" (3) from "broken" (1)
    and "asked wrongly" (2)."""

    exit_code = 3
