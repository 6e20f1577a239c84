"""Inference back ends: onnxruntime (CPU) and LiteRT (ai-edge-litert) for .tflite."""
from __future__ import annotations

import pathlib

import numpy as np


class OnnxBackend:
    def __init__(self, path: str | pathlib.Path, threads: int = 2):
        import onnxruntime as ort

        opts = ort.SessionOptions()
        opts.intra_op_num_threads = max(1, threads)
        opts.inter_op_num_threads = 1
        opts.log_severity_level = 3
        # No busy-waiting between kernels: the network shares the CPU with tracking.
        opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
        try:
            self.session = ort.InferenceSession(str(path), sess_options=opts,
                                                providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own Fail / InvalidGraph types
            raise ValueError(f"{path}: onnxruntime cannot load the model ({exc})") from None
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        if len(inputs) != 1 or not outputs:
            raise ValueError(f"{path}: expected one image input and a label or logit output, "
                             f"got {len(inputs)} inputs and {len(outputs)} outputs")
        self.input_name = inputs[0].name
        self.input_shape = tuple(inputs[0].shape)

    def run(self, x: np.ndarray) -> np.ndarray:
        return self.session.run(None, {self.input_name: x})[0]


class TfliteBackend:
    def __init__(self, path: str | pathlib.Path, threads: int = 2):
        try:
            from ai_edge_litert.interpreter import Interpreter
        except ImportError:
            raise ValueError(f"{path}: a .tflite model needs the ai-edge-litert package "
                             "(pip install ai-edge-litert), or convert it to ONNX") from None
        try:
            self.interpreter = Interpreter(model_path=str(path), num_threads=max(1, threads))
            self.interpreter.allocate_tensors()
        except (ValueError, RuntimeError) as exc:
            raise ValueError(f"{path}: LiteRT cannot load the model ({exc})") from None
        inp = self.interpreter.get_input_details()
        if len(inp) != 1:
            raise ValueError(f"{path}: expected one image input, got {len(inp)}")
        self.input_index = inp[0]["index"]
        self.input_shape = tuple(int(v) for v in inp[0]["shape"])
        self.output_index = self.interpreter.get_output_details()[0]["index"]

    def run(self, x: np.ndarray) -> np.ndarray:
        # LiteRT interpreters are not re-entrant: one Segmenter per thread.
        self.interpreter.set_tensor(self.input_index, x)
        self.interpreter.invoke()
        return self.interpreter.get_tensor(self.output_index)


def open_backend(kind: str, path: str | pathlib.Path, threads: int = 2):
    if not pathlib.Path(path).is_file():
        raise FileNotFoundError(f"{path}: model file does not exist")
    if kind == "onnx":
        return OnnxBackend(path, threads)
    if kind == "tflite":
        return TfliteBackend(path, threads)
    raise ValueError(f"{path}: unknown backend {kind!r}")
