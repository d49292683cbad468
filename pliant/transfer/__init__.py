"""The proxies' side that runs the environments (thesis §4.1.1): a proxy's strategy transferred
to the FEM robot (`pliant.transfer.proxy`), the FEM's pushes replayed on the proxy
(`pliant.transfer.pushes`), and the ``pliant proxy`` command group. The proxies themselves,
their builders and calibration sit below the environments, in :mod:`pliant.proxy`.
"""
