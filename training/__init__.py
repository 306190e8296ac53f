"""Training pilots: the library the application's ``train`` command and trainer console use.

:mod:`training.trainer` (``train``: data to model file) over :mod:`training.dataset` (tub records
to tensors, with :mod:`~training.augment`, :mod:`~training.balance`, :mod:`~training.split`,
:mod:`~training.framecache`, :mod:`~training.prefetch`), :mod:`training.fit` (the epoch loop, with
:mod:`~training.acceleration` and :mod:`~training.distributed`), :mod:`training.hyperparams` (the
console's and the CLI's view of the training settings), :mod:`training.model_db` (the car's model
db), :mod:`training.export` and :mod:`training.quantize` (ONNX, TorchScript, int8).

No part imports this package (tests/vehicle/test_layers.py checks it): what runs on the car lives
in :mod:`parts.pilots` (models, preprocessing, runtimes, the model file). Its settings are
declared in :mod:`training.settings`.
"""
