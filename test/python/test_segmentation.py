"""Segmentation: model cards, back ends, pre/post-processing, real models on a real frame."""
from __future__ import annotations

import json
import pathlib

import cv2
import numpy as np
import pytest

from dynaorb.segmentation import InputSpec, ModelCard, Segmenter, load_card
from dynaorb.segmentation.labels import PASCAL_VOC

PERSON = 15
TUM_FRAME = "tum/rgbd_dataset_freiburg3_walking_xyz_fragment/rgb/1341846313.592026.png"
# Marked by hand on that frame. Inner boxes lie inside each body (head, torso,
# legs); outer boxes enclose each person with chair and desk around them.
SEATED_INNER = [(100, 130, 145, 195), (58, 200, 135, 380), (135, 330, 230, 385), (180, 390, 210, 460)]
STANDING_INNER = [(495, 20, 555, 85), (500, 90, 630, 330), (490, 350, 590, 470)]
OUTER = [(45, 115, 250, 480), (475, 5, 640, 480)]


def models_dir(data: pathlib.Path) -> pathlib.Path:
    d = data.parent / "models" / "segmentation"
    if not d.is_dir():
        pytest.skip(f"models not found at {d}")
    return d


def tiny_model(path: pathlib.Path, layout: str) -> None:
    """A 2-class network on an 8x8 input: class 1 where the red channel is bright.

    NHWC: uint8 input, logits out (channels last). NCHW: float32 input
    normalised by the card, ArgMax labels out (int64), like DeepLab's export.
    """
    import onnx
    from onnx import TensorProto, helper

    if layout == "NHWC":
        nodes = [
            helper.make_node("Cast", ["x"], ["xf"], to=TensorProto.FLOAT),
            helper.make_node("Slice", ["xf", "s0", "s1", "ax"], ["r"]),          # R channel: 1x8x8x1
            helper.make_node("Sub", ["r", "half"], ["pos"]),
            helper.make_node("Neg", ["pos"], ["neg"]),
            helper.make_node("Concat", ["neg", "pos"], ["y"], axis=3),           # 1x8x8x2 logits
        ]
        inp = helper.make_tensor_value_info("x", TensorProto.UINT8, [1, 8, 8, 3])
        out = helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 8, 8, 2])
        inits = [helper.make_tensor("s0", TensorProto.INT64, [1], [0]),
                 helper.make_tensor("s1", TensorProto.INT64, [1], [1]),
                 helper.make_tensor("ax", TensorProto.INT64, [1], [3]),
                 helper.make_tensor("half", TensorProto.FLOAT, [], [128.0])]
    else:
        nodes = [
            helper.make_node("Slice", ["x", "s0", "s1", "ax"], ["r"]),           # 1x1x8x8, normalised R
            helper.make_node("Neg", ["r"], ["neg"]),
            helper.make_node("Concat", ["neg", "r"], ["logits"], axis=1),
            helper.make_node("ArgMax", ["logits"], ["y"], axis=1, keepdims=0),   # 1x8x8 int64
        ]
        inp = helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 3, 8, 8])
        out = helper.make_tensor_value_info("y", TensorProto.INT64, [1, 8, 8])
        inits = [helper.make_tensor("s0", TensorProto.INT64, [1], [0]),
                 helper.make_tensor("s1", TensorProto.INT64, [1], [1]),
                 helper.make_tensor("ax", TensorProto.INT64, [1], [1])]
    graph = helper.make_graph(nodes, "tiny", [inp], [out], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, str(path))


def tiny_card(path: pathlib.Path, layout: str, **changes) -> ModelCard:
    spec = InputSpec(8, 8, layout=layout, dtype="uint8" if layout == "NHWC" else "float32", color="RGB",
                     mean=None if layout == "NHWC" else [128.0, 128.0, 128.0],
                     std=None if layout == "NHWC" else [64.0, 64.0, 64.0])
    card = ModelCard(name="tiny", file=path.name, backend="onnx", input=spec, labels=["background", "red"],
                     movable=[1], output="logits" if layout == "NHWC" else "labels")
    for k, v in changes.items():
        setattr(card, k, v)
    card.save(path.with_name(path.name + ".card.json"))
    return card


def red_left_half(h=30, w=40) -> np.ndarray:
    img = np.full((h, w, 3), 40, np.uint8)
    img[:, : w // 2, 2] = 230  # BGR: red on the left
    return img


@pytest.mark.parametrize("layout", ["NHWC", "NCHW"])
def test_tiny_model_pre_and_post_processing(tmp_path, layout):
    model = tmp_path / f"tiny_{layout}.onnx"
    tiny_model(model, layout)
    tiny_card(model, layout)
    seg = Segmenter(model)
    result = seg.segment(red_left_half())
    assert result.labels.shape == (30, 40) and result.labels.dtype == np.uint8
    # Left half red -> class 1; the boundary may move by one 8x8 cell (5 px here).
    assert np.all(result.labels[:, :15] == 1) and np.all(result.labels[:, 25:] == 0)
    mask = seg.movable_mask(result.labels)
    assert set(np.unique(mask)) == {0, 255} and np.array_equal(mask == 255, result.labels == 1)
    # Grey input is replicated to three channels: dark -> background, bright -> class 1.
    assert not seg.segment(np.full((30, 40), 60, np.uint8)).labels.any()
    assert seg.segment(np.full((30, 40), 200, np.uint8)).labels.all()


def test_card_errors_name_the_problem(tmp_path):
    model = tmp_path / "tiny.onnx"
    tiny_model(model, "NHWC")
    with pytest.raises(ValueError, match="no model card tiny.onnx.card.json"):
        load_card(model)
    tiny_card(model, "NHWC", movable=[5])
    with pytest.raises(ValueError, match=r"movable ids \[5\]"):
        Segmenter(model)
    tiny_card(model, "NHWC", input=InputSpec(16, 16))
    with pytest.raises(ValueError, match="does not match its card"):
        Segmenter(model)
    card = model.with_name("tiny.onnx.card.json")
    d = json.loads(card.read_text())
    del d["labels"]
    card.write_text(json.dumps(d))
    with pytest.raises(ValueError, match="missing or unexpected key"):
        Segmenter(model)
    card.write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        Segmenter(model)
    tiny_card(model, "NHWC")
    model.write_bytes(b"garbage")
    with pytest.raises(ValueError, match="onnxruntime cannot load"):
        Segmenter(model)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        Segmenter(tmp_path / "deeplabv3_mnv2_pascal_quant.onnx")


def test_bad_images_are_rejected_clearly(data):
    seg = Segmenter(models_dir(data) / "deeplabv3_mnv2_dm05_pascal_quant.onnx")
    with pytest.raises(ValueError, match="8-bit"):
        seg.segment(np.zeros((20, 20, 3), np.float32))
    with pytest.raises(ValueError, match="grey or 3-channel"):
        seg.segment(np.zeros((0, 0), np.uint8))


def box_fraction(mask: np.ndarray, boxes) -> float:
    sel = np.zeros(mask.shape, bool)
    for x0, y0, x1, y1 in boxes:
        sel[y0:y1, x0:x1] = True
    return float(mask[sel].mean())


@pytest.mark.parametrize("name", ["deeplabv3_mnv2_pascal_quant", "deeplabv3_mnv2_dm05_pascal_quant"])
def test_both_people_found_on_a_real_frame(data, name):
    image = cv2.imread(str(data / TUM_FRAME))
    seg = Segmenter(models_dir(data) / f"{name}.onnx")
    person = seg.segment(image).labels == PERSON
    assert box_fraction(person, SEATED_INNER) >= 0.80
    assert box_fraction(person, STANDING_INNER) >= 0.80
    outside = np.ones(person.shape, bool)
    for x0, y0, x1, y1 in OUTER:
        outside[y0:y1, x0:x1] = False
    assert person[outside].mean() <= 0.05


def test_every_shared_model_runs_and_tflite_agrees_with_onnx(data):
    image = cv2.imread(str(data / TUM_FRAME))
    models = models_dir(data)
    for onnx_file in sorted(models.glob("*.onnx")):
        seg = Segmenter(onnx_file)
        labels = seg.segment(image).labels
        assert labels.shape == image.shape[:2]
        names = seg.card.labels
        assert "person" in names and int(np.max(labels)) < len(names)
        person = labels == names.index("person")
        assert box_fraction(person, STANDING_INNER) >= 0.5, onnx_file.name
        tflite = Segmenter(onnx_file.with_suffix(".tflite"))
        assert tflite.card.backend == "tflite"
        # Same network, two runtimes: quantised kernels may differ on a few boundary pixels.
        assert np.mean(tflite.segment(image).labels == labels) >= 0.98, onnx_file.name
    assert Segmenter(models / "deeplabv3_mnv2_pascal_quant.onnx").card.labels == list(PASCAL_VOC)
