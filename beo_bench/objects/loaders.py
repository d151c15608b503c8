"""Placeholder replaced by the dataset loaders."""


def load_shapenet(path, **kw):
    raise NotImplementedError


load_modelnet = load_folder = load_any = load_shapenet
