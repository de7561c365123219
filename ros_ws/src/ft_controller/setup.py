from setuptools import find_packages, setup

package_name = "ft_controller"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/launch", ["launch/controller.launch.py"]),
        ("share/" + package_name + "/config", ["config/controller.yaml",
                                               "config/sros2_policy.xml",
                                               "config/diagnostic_aggregator.yaml"]),
    ],
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},  # colcon test runs test/ with pytest
    zip_safe=False,
    maintainer="ft-arms maintainers",
    maintainer_email="maintainers@ft-arms.org",
    description="Fault-tolerant redundancy-resolution controller node for redundant arms.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "controller_node = ft_controller.controller_node:main",
        ],
    },
)
